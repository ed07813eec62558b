"""Report tables: rendering (Table 3 beside the paper: tests/test_replicates.py)."""

import pytest

from toolpath.reports.tables import Table


def test_markdown_and_latex_render_the_same_cells():
    table = Table("T_1 & more", ["a", "b %"])
    table.add(["x_y", "**1.00**"])
    md, tex = table.markdown(), table.latex()
    assert "| x_y | **1.00** |" in md and "\n|---|---|\n" in md
    assert r"x\_y & \textbf{1.00} \\" in tex and r"\caption{T\_1 \& more}" in tex and r"b \%" in tex
    with pytest.raises(ValueError, match="2 columns"):
        table.add(["only one"])




def test_table4b_states_each_int8_target_met_or_not():
    from toolpath.reports.speed import int8_gains

    def entry(params, same, fastest, ratio, runtime="openvino"):
        return {"parameters": params, f"int8_speedup_{runtime}": same, "int8_speedup_eager": 0.5,
                "fp32_onnx_file_bytes": 1000, "int8_onnx_file_bytes": int(1000 * ratio),
                "shipped": {"runtime": runtime, "speedup_same_runtime": same, "speedup_vs_fastest_fp32": fastest,
                            "accuracy_drop_points": {"gear": 0.25}}}

    inference = {"models": {"mcrl": entry(400_000, 1.20, 1.05, 0.5), "cnn": entry(400_000, 1.6, 1.2, 0.3),
                            "maxvit": entry(400_000, 1.6, 1.2, 0.8), "mlp": entry(40_000, 1.0, 1.0, 0.9),
                            "rnn": {"parameters": 150_000, "shipped": {"runtime": None, "why": "no runtime keeps"}}}}
    qat = {"gear": {m: {"tensor_bytes": {"int8": 30, "float32": 10}, "fp32_tensor_bytes": {"float32": 100}}
                    for m in ("mcrl", "cnn", "maxvit", "mlp")}}
    rows = {r[0]: r for r in int8_gains(inference, qat).rows}
    assert rows["mcrl"][-1].startswith("met") and "OpenVINO: 1.20x / 1.05x" in rows["mcrl"]
    assert rows["mcrl"][-4] == "0.40x"  # INT8 weights 40 of FP32's 100 bytes
    assert rows["cnn"][-1].startswith("met") and rows["cnn"][-2] == "gear +0.25"
    assert "fastest" not in rows["cnn"][-1]  # 1.2x the fastest FP32 too
    inference["models"]["cnn"]["shipped"]["speedup_vs_fastest_fp32"] = 0.75
    assert int8_gains(inference, qat).rows[1][-1].endswith("slower than the fastest FP32 (0.75x)")
    assert rows["maxvit"][-1].startswith("not met")  # fast enough, but its file is 0.8x FP32's
    assert rows["mlp"][-1].startswith("none") and rows["rnn"][-1] == "not met"


def test_table4c_shows_each_runtimes_fp32_and_int8_time_and_what_the_int8_time_is_spent_on():
    from toolpath.reports.speed import int8_profile

    def profile(ms, shares, kinds):
        return {"ms_per_run": ms, "share_by_op": shares, "share_by_kind": dict(zip(("integer", "convert", "float"),
                                                                                   kinds, strict=True))}

    slow = profile(40.0, {"Add [jit_avx2_f32]": 0.05, "FullyConnected [jit_gemm_I8]": 0.7, "Reorder [ref]": 0.02,
                          "Transpose [unknown_f32]": 0.2, "other": 0.03},
                   (0.72, 0.08, 0.2))
    inference = {"setup": {"batch": 256}, "models": {"convnext": {"op_profile": {
        "openvino": {"fp32": profile(28.0, {"FullyConnected [brgemm_avx2_f32]": 1.0}, (0, 0, 1)), "int8": slow}}},
        "mlp": {}}}  # a model without an INT8 file has no profile: no row
    rows = int8_profile(inference).rows
    assert rows == [["convnext", "OpenVINO", "28.00", "40.00", "72 % / 8 % / 20 %",
                     "FullyConnected [jit_gemm_I8] 70 %, Transpose [unknown_f32] 20 %, Add [jit_avx2_f32] 5 %"]]


@pytest.mark.parametrize(("passes", "said"), [(1, "one pass, timed once"), (3, "the median of 3 passes")])
def test_table4_notes_say_how_the_split_was_timed_and_on_what_cpu(passes, said):
    from toolpath.reports.speed import table4

    setup = {"split_repeats": passes, "repeats": 5, "batch": 256, "int8_dot_product": "none (AVX2: vpmaddubsw)",
             "fp32_onnx_form": "the INT8 graph's (1-D convolutions as 2-D)"}
    notes = " ".join(table4({"setup": setup, "models": {}}, ["gear"]).notes)
    assert said in notes and "INT8 dot product: none (AVX2: vpmaddubsw)" in notes
    assert "exported in the INT8 graph's (1-D convolutions as 2-D) form" in notes
