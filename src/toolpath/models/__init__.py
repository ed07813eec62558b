"""Window classifiers: MCRL, its seven baselines, the exact LocalCurvature rule, one registry."""

from toolpath.models.classic import CNN, LSTM, MLP, RNN
from toolpath.models.inputs import prepare, random_reversal, random_rotation_reflection
from toolpath.models.mcrl import MCRL
from toolpath.models.modern import ConvMixer1d, ConvNeXt1d, MaxViT1d
from toolpath.models.registry import build, is_learned
from toolpath.models.rule import LocalCurvatureRule

__all__ = [
    "CNN", "LSTM", "MCRL", "MLP", "RNN", "ConvMixer1d", "ConvNeXt1d",
    "LocalCurvatureRule", "MaxViT1d", "build", "is_learned", "prepare", "random_reversal", "random_rotation_reflection",
]
