"""Training and evaluation of the window classifiers: the loop, and the scikit-learn estimator around it."""

from toolpath.training.classifier import TorchClassifier
from toolpath.training.loop import EpochRecord, TrainSettings, fit_network, predict_logits

__all__ = ["EpochRecord", "TorchClassifier", "TrainSettings", "fit_network", "predict_logits"]
