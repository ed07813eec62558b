"""Table 4: inference time FP32 and INT8 per model and shape, from ``reports/metrics/inference.json``.

Our workload is stated (each shape's whole test split, batch 256, torch threads fixed); the paper's
Table 4 gives seconds for a workload it does not state, so only the ordering of its figures is
comparable with ours, not their size.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

from toolpath.reports.paper import PAPER_MODELS
from toolpath.reports.tables import Table

VARIANTS = (("fp32_eager", "torch FP32"), ("int8_eager", "torch INT8 (reference graph)"),
            ("fp32_compiled", "inductor FP32"), ("int8_compiled", "inductor INT8"),
            ("onnxruntime_fp32", "ONNX Runtime FP32"), ("onnxruntime_int8", "ONNX Runtime INT8"),
            ("openvino_fp32", "OpenVINO FP32"), ("openvino_int8", "OpenVINO INT8"))
# the file each variant runs: its size is the model's size in that runtime
FILE_KEYS = {"fp32_eager": "fp32_file_bytes", "fp32_compiled": "fp32_file_bytes", "int8_eager": "int8_file_bytes",
             "int8_compiled": "int8_file_bytes", "onnxruntime_fp32": "fp32_onnx_file_bytes",
             "openvino_fp32": "fp32_onnx_file_bytes", "onnxruntime_int8": "int8_onnx_file_bytes",
             "openvino_int8": "int8_onnx_file_bytes"}
RUNTIME_NAMES = {"eager": "torch", "compiled": "inductor", "onnxruntime": "ONNX Runtime", "openvino": "OpenVINO"}
# issue 22's targets: MCRL INT8 at least the paper's 3.2 / 2.8 s ratio; larger models 1.5x and 0.7x the file
PAPER_MCRL_SPEEDUP = 3.2 / 2.8
LARGE_MODEL_PARAMETERS, LARGE_SPEEDUP, LARGE_WEIGHT_RATIO, LARGE_FILE_RATIO = 100_000, 1.5, 0.5, 0.7


def _paper(paper: Mapping, model: str, variant: str, shape: str) -> float | None:
    key = model if variant.startswith("fp32") else f"{model}_int8"
    return paper.get(key, {}).get(shape)


def table4(inference: Mapping, shapes: Sequence[str]) -> Table:
    """Per model and variant: seconds to classify each shape's test split (paper's seconds beside),
    windows per second at batch 256 and latency at batch 1; the exact rule last."""
    setup = inference.get("setup", {})
    headers = ["model", "variant", *(f"{s}: test split s (paper s)" for s in shapes),
               f"windows/s (batch {setup.get('batch', '?')})", "latency batch 1 (ms)", "file size (kB)"]
    table = Table("Table 4: inference time, ours (stated workload) beside the paper's seconds", headers)
    order, paper_s = list(PAPER_MODELS), inference.get("paper_table4_s", {})  # the paper's row order, then others
    models = inference.get("models", {})
    for model in sorted(models, key=lambda m: (order.index(m) if m in order else len(order), m)):
        entry = models[model]
        for variant, name in VARIANTS:
            if variant not in entry:
                continue
            cells: list[object] = [model, name]
            for shape in shapes:
                split = entry.get("test_split_s", {}).get(shape, {})
                ours = split.get(variant)
                paper = _paper(paper_s, model, variant, shape)
                text = f"{ours:.4f}" if ours is not None else "-"
                cells.append(f"{text} ({paper:g})" if paper is not None else f"{text} (-)")
            size = entry.get(FILE_KEYS[variant])
            cells += [f"{entry[variant]['windows_per_s']:,.0f}", f"{entry[variant]['latency_b1_ms']:.2f}",
                      f"{size / 1e3:,.0f}" if size else "-"]
            table.add(cells)
    rule = inference.get("rule")
    if rule:
        cells = ["rule", "numpy (exact LocalCurvature)"]
        cells += [f"{rule['test_split_s'][s]:.4f} (-)" if s in rule.get("test_split_s", {}) else "-" for s in shapes]
        cells += [f"{rule['windows_per_s']:,.0f}", f"{rule['latency_b1_ms']:.2f}", "0"]
        table.add(cells)
    windows = {s: next((e["test_split_s"][s]["windows"] for e in inference.get("models", {}).values()
                        if s in e.get("test_split_s", {})), "?") for s in shapes}
    table.notes += [
        "Workload: the whole test split of each shape (" + ", ".join(f"{s} {n} windows" for s, n in windows.items())
        + ") classified in one call per variant (the split's seconds: "
        + (("one pass, timed once" if setup["split_repeats"] == 1 else f"the median of {setup['split_repeats']} passes")
           if "split_repeats" in setup else "the median of `benchmark.split_repeats` passes")
        + f"); windows/s at batch {setup.get('batch', '?')} and latency at batch 1: medians of "
        f"{setup.get('repeats', '?')} interleaved repetitions, each variant's turn opening with a pause and an "
        "untimed call (the previous runtime's threads spin on after its call); "
        f"{setup.get('torch_threads', '?')} torch threads on {setup.get('cpu', '?')} "
        f"({setup.get('cores', '?')} cores"
        + (f", INT8 dot product: {setup['int8_dot_product']}" if "int8_dot_product" in setup else "") + "), "
        f"torch {setup.get('torch', '?')}. The paper's seconds are for a workload it does not state, on a GPU: "
        "compare orderings, not sizes.",
        "The eager INT8 graph simulates INT8 arithmetic in float (dequantize -> op -> quantize), so it is slower than "
        "FP32 by construction; INT8 kernels run in the compiled graph and in ONNX Runtime and OpenVINO, which run "
        "the qat stage's ONNX files (the QAT graph with its learned scales, `models/int8/<model>/<shape>.onnx`)"
        + (f"; the FP32 ONNX file they are timed against is exported in {setup['fp32_onnx_form']} form"
           if "fp32_onnx_form" in setup else "") + ".",
    ]
    return table


def int8_gains(inference: Mapping, qat: Mapping[str, Mapping]) -> Table:
    """Per model: INT8's speed-up over FP32 in each runtime and over the fastest FP32 anywhere, the
    INT8 / FP32 file size ratio, the shipped runtime and its accuracy drop per shape, and whether the
    targets of issue 22 hold (MCRL >= the paper's 3.2 / 2.8 s; > 100 k parameters: >= 1.5x, weights
    <= 0.5x and file <= 0.7x; weights from the first shape's qat record)."""
    table = Table("Table 4b: INT8 against FP32 per runtime (speed-up at batch 256), file sizes, the shipped runtime",
                  ["model", "parameters", *(f"{RUNTIME_NAMES[r]} INT8/FP32" for r in RUNTIME_NAMES),
                   "shipped runtime: vs same-runtime FP32 / vs fastest FP32", "INT8 / FP32 weights",
                   "INT8 / FP32 ONNX file",
                   "accuracy drop (points, per shape)", "target"])
    for model, entry in inference.get("models", {}).items():
        ship = entry.get("shipped") or {}
        best = ship.get("runtime")
        speed = [f"{entry[f'int8_speedup_{r}']:.2f}x" if f"int8_speedup_{r}" in entry else "-" for r in RUNTIME_NAMES]
        ratio = (entry["int8_onnx_file_bytes"] / entry["fp32_onnx_file_bytes"]
                 if entry.get("int8_onnx_file_bytes") and entry.get("fp32_onnx_file_bytes") else None)
        drops = ship.get("accuracy_drop_points") or {s: qat.get(s, {}).get(model, {}).get("accuracy_drop_points")
                                                     for s in qat}
        params = entry.get("parameters", 0)
        first = next(iter(qat.values()), {}).get(model, {})
        weights = (sum(first["tensor_bytes"].values()) / sum(first["fp32_tensor_bytes"].values())
                   if first.get("tensor_bytes") and first.get("fp32_tensor_bytes") else None)
        if best is None:
            shipped_cell, verdict = f"none ({ship.get('why', 'no INT8 file')[:80]})", "not met"
        else:
            same, fastest = ship["speedup_same_runtime"], ship["speedup_vs_fastest_fp32"]
            shipped_cell = f"{RUNTIME_NAMES[best]}: {same:.2f}x / {fastest:.2f}x"
            if model == "mcrl":
                met = same >= PAPER_MCRL_SPEEDUP and fastest >= 1.0
                verdict = f"{'met' if met else 'not met'} (>= {PAPER_MCRL_SPEEDUP:.2f}x, >= 1x fastest)"
            elif params > LARGE_MODEL_PARAMETERS:
                met = (same >= LARGE_SPEEDUP and ratio is not None and ratio <= LARGE_FILE_RATIO
                       and weights is not None and weights <= LARGE_WEIGHT_RATIO)
                verdict = (f"{'met' if met else 'not met'} (>= {LARGE_SPEEDUP}x the same runtime's FP32, weights <= "
                           f"{LARGE_WEIGHT_RATIO}x, file <= {LARGE_FILE_RATIO}x)")
                if fastest < 1.0:  # a same-runtime gain that still loses to FP32 elsewhere is said so
                    verdict += f"; slower than the fastest FP32 ({fastest:.2f}x)"
            else:
                verdict = "none (<= 100 k parameters)"
        table.add([model, f"{params:,}", *speed, shipped_cell, f"{weights:.2f}x" if weights else "-",
                   f"{ratio:.2f}x" if ratio else "-",
                   ", ".join(f"{s} {d:+.2f}" if d is not None else f"{s} -" for s, d in drops.items()), verdict])
    table.notes += [
        "Speed-ups are windows/s ratios measured side by side in one run (interleaved repetitions, medians). The "
        "shipped runtime is the fastest INT8 runtime whose INT8 file keeps every shape's test accuracy within "
        "`benchmark.max_drop_points` of the FP32 network; `toolpath smooth --classifier MODEL.onnx "
        "--runtime R` runs it. The paper's INT8 MCRL is 3.2 -> 2.8 s on gear (1.14x); where a target is not met, "
        "Table 4c shows why: each runtime's per-operator profile of the FP32 and the INT8 file (what stays float, "
        "and how fast the integer kernels are).",
    ]
    return table


def int8_profile(inference: Mapping) -> Table:
    """Table 4c: where each runtime spends an INT8 file's time against the FP32 file's, from the
    runtime's own profiler at the throughput batch (the benchmark's ``op_profile``): why INT8 is or
    is not faster."""
    table = Table("Table 4c: where INT8 time goes (each runtime's profiler, batch "
                  f"{inference.get('setup', {}).get('batch', '?')})",
                  ["model", "runtime", "FP32 ms / batch", "INT8 ms / batch", "INT8 time: integer / convert / float",
                   "largest INT8 operators"])
    for model, entry in inference.get("models", {}).items():
        for runtime, pair in entry.get("op_profile", {}).items():
            fp32, int8 = pair["fp32"], pair["int8"]
            kind = int8["share_by_kind"]
            ranked = sorted(((v, op) for op, v in int8["share_by_op"].items() if op != "other"), reverse=True)
            largest = [f"{op} {100 * v:.0f} %" for v, op in ranked[:3]]  # the JSON keeps its keys sorted by name
            table.add([model, RUNTIME_NAMES[runtime], f"{fp32['ms_per_run']:.2f}", f"{int8['ms_per_run']:.2f}",
                       " / ".join(f"{100 * kind[k]:.0f} %" for k in ("integer", "convert", "float")),
                       ", ".join(largest)])
    table.notes += [
        "Milliseconds are the sum of the operators' times in the runtime's profiler (threads fixed as above), so they "
        "run a little under the timed figures. Integer: kernels computing in int8 (ONNX Runtime's QLinear* / "
        "*Integer, OpenVINO's *_I8 kernels); convert: quantize / dequantize and layout reorders; float: the rest, "
        "which INT8 leaves unquantised. Where the integer kernels alone take longer than the FP32 file's whole "
        "run, INT8 cannot be faster however little stays float: the int8 kernels themselves are slow on this CPU "
        "(see the machine in the Table 4 notes).",
    ]
    return table


# issue 45's targets for recurrences exported as recurrences: files against checkpoints, MCRL's nodes, and
# MCRL in ONNX Runtime against the file shipped when the issue was written (the exporter's own unrolling)
NATIVE_FILE_RATIO, MCRL_MAX_NODES, MCRL_MIN_ORT_SPEEDUP = 2.0, 150, 1.5
FORM_NAMES = {"shipped": "shipped (lean)", "exporter": "exporter's unrolling", "native": "native",
              "unhoisted": "unhoisted", "compact": "compact (Scan loops)"}


def _form_target(model: str, row: Mapping) -> str:
    if model != "mcrl":
        met = row["bytes_vs_checkpoint"] <= NATIVE_FILE_RATIO
        return f"{'met' if met else 'not met'} (file <= {NATIVE_FILE_RATIO:.0f}x checkpoint)"
    nodes = row["nodes"] + row.get("loop_body_nodes", 0) <= MCRL_MAX_NODES  # a loop's body counts too
    speed = row["speed_vs_exporter"]["onnxruntime"] >= MCRL_MIN_ORT_SPEEDUP
    return (f"<= {MCRL_MAX_NODES} nodes: {'met' if nodes else 'not met'}; ONNX Runtime >= {MCRL_MIN_ORT_SPEEDUP}x "
            f"the exporter's unrolling: {'met' if speed else 'not met'}")


def recurrent_forms(inference: Mapping) -> Table:
    """Table 4d: each recurrent network's FP32 ONNX file as shipped (the lean form), as torch's exporter
    unrolls it, with its tanh RNNs as ONNX ``RNN`` nodes, and (MCRL) unrolled without the hoisted input
    projection and in its compact form, timed side by side in one run, with issue 45's targets."""
    runtimes = ("onnxruntime", "openvino")
    table = Table("Table 4d: recurrences in ONNX, shipped (lean form), as torch's exporter unrolls them, as RNN / "
                  "LSTM nodes (native), unrolled without MCRL's hoist (unhoisted), or with Scan loops (compact); "
                  f"FP32, batch "
                  f"{inference.get('setup', {}).get('batch', '?')}",
                  ["model", "form", "nodes (recurrent)", "file kB", "file / checkpoint",
                   *(f"{RUNTIME_NAMES[r]} windows/s (vs exporter's)" for r in runtimes), "largest |logit - torch|",
                   "target"])
    faster = []
    for model, entry in inference.get("models", {}).items():
        for form, row in (entry.get("recurrent_forms") or {}).items():
            ratio = row.get("speed_vs_exporter", {})
            rates = [f"{row[f'{r}_windows_per_s']:,.0f}" + (f" ({ratio[r]:.2f}x)" if form != "exporter" else "")
                     for r in runtimes]
            diff = max(row[f"{r}_max_logit_diff"] for r in runtimes)
            loops = f" + {row['loop_body_nodes']} in loops" if row.get("loop_body_nodes") else ""
            table.add([model, FORM_NAMES.get(form, form), f"{row['nodes']}{loops} ({row['recurrent_nodes']})",
                       f"{row['file_bytes'] / 1e3:,.0f}", f"{row['bytes_vs_checkpoint']:.2f}x", *rates, f"{diff:.1e}",
                       _form_target(model, row)])
            if form in ("native", "compact") and "shipped" in entry["recurrent_forms"]:
                shipped = entry["recurrent_forms"]["shipped"]["speed_vs_exporter"]
                faster += [f"{model} {FORM_NAMES[form]} in {RUNTIME_NAMES[r]}"
                           for r in runtimes if ratio[r] > shipped[r]]
    if not table.rows:
        table.notes.append("Not measured in this run: `benchmark.recurrent_forms` names none of the benchmarked "
                           "models.")
        return table
    table.notes += [
        "Every form is the same function (largest logit difference from the torch network on the timed batch). "
        "The shipped files are the lean form: linear layers on a sequence as one Gemm over its points "
        "(`toolpath.inference.lean`), and each tanh RNN as one projection of all its steps, then per step one Gemm "
        "(taking that step's projection as its bias) and its Tanh (`toolpath.inference.recurrences.STEPWISE`). "
        "Torch's exporter writes an LSTM as one node but unrolls a tanh RNN into MatMul / Add / Tanh chains (the "
        "form shipped before); the native form maps it "
        "to the ONNX RNN operator and runs MCRL's first RNN on its fused input; the unhoisted form is that same "
        "layer unrolled, projecting the fused input at every step (the form before MCRL's hoist). The compact form "
        "(`toolpath.inference.compact`, MCRL on the turning terms) is written from the weights: its three tanh RNNs "
        "one Scan loop whose body steps every layer (Gemm, Tanh), each branch's resampling, linear layer and "
        "attention projections folded into one product; its nodes count the loop's body too. In brackets: "
        "windows per second against the exporter's unrolling, measured side by side in one run (interleaved "
        "repetitions, medians). Files carry no per-node provenance (module paths, stack traces).",
        ("Faster than the shipped form in this run: " + ", ".join(faster) + ".") if faster
        else "The shipped form was the fastest in every runtime in this run: each runtime's RNN kernel ran slower "
             "than the Gemms of the unrolled steps (`make bench`: reports/bench/recurrences.json times one layer "
             "each way), and the compact form's loops cost a little more per step than the steps written out.",
    ]
    return table
