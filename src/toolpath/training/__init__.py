"""Training and evaluation of the window classifiers."""

from toolpath.training.loop import EpochRecord, TrainSettings, fit_network, predict_logits

__all__ = ["EpochRecord", "TrainSettings", "fit_network", "predict_logits"]
