"""The training-step benchmark (toolpath.bench.train_steps): FLOPs against a hand count, the fused
recurrent layers marked uncounted, the stage's seconds at the matrix-product rate."""

import pytest
import torch

from conftest import REPO
from toolpath.bench.train_steps import measure, step_figures
from toolpath.pipeline.config import compose_config as compose


def test_a_linear_layers_step_counts_its_two_products():
    # forward x (8 x 100) @ W^T (100 x 4): 2 * 8 * 100 * 4; backward: the weight's gradient, a product of the
    # same size (the windows themselves need no gradient)
    model = torch.nn.Sequential(torch.nn.Flatten(), torch.nn.Linear(100, 4))
    figures = step_figures(model, batch=8, repeats=2)
    assert figures["step_flops"] == 2 * 2 * 8 * 100 * 4
    assert figures["step_s"] > 0 and figures["flop_per_s"] == pytest.approx(figures["step_flops"] / figures["step_s"])
    assert figures["uncounted"] is None


def test_models_get_their_share_of_the_peak_and_a_fused_recurrence_is_not_under_counted():
    models = compose(REPO, []).models
    threads = torch.get_num_threads()
    result = measure({"mlp": models.mlp, "lstm": models.lstm, "rule": models.rule}, batch=8, threads=1, repeats=2,
                     stage_seconds={"train@mlp": 10.0, "train@lstm": 20.0})
    assert set(result["models"]) == {"mlp", "lstm"}  # the exact rule does not train
    mlp, lstm = result["models"]["mlp"], result["models"]["lstm"]
    assert mlp["step_flops"] > 0 and 0 < mlp["share_of_gemm_peak"] == pytest.approx(
        mlp["flop_per_s"] / mlp["gemm_flop_per_s"])
    assert mlp["train_stage_s_at_gemm_peak"] == pytest.approx(10.0 * mlp["share_of_gemm_peak"])
    assert lstm["step_flops"] is None and lstm["uncounted"] == ["LSTM"] and lstm["train_stage_s_at_gemm_peak"] is None
    assert result["counted_train_stages_s"] == 10.0
    assert torch.get_num_threads() == threads  # the caller's thread count is left as it was
