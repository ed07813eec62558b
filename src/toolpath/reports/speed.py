"""Table 4: inference time FP32 and INT8 per model and shape, from ``reports/metrics/inference.json``.

Our workload is stated (each shape's whole test split, batch 256, torch threads fixed); the paper's
Table 4 gives seconds for a workload it does not state, so only the ordering of its figures is
comparable with ours, not their size.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

from toolpath.reports.paper import TABLE4
from toolpath.reports.tables import Table

VARIANTS = (("fp32_eager", "FP32 eager"), ("int8_eager", "INT8 eager (reference graph)"),
            ("fp32_compiled", "FP32 compiled"), ("int8_compiled", "INT8 compiled"))


def _paper(model: str, variant: str, shape: str) -> float | None:
    key = model if variant.startswith("fp32") else f"{model}_int8"
    return TABLE4.get(key, {}).get(shape)


def table4(inference: Mapping, shapes: Sequence[str]) -> Table:
    """Per model and variant: seconds to classify each shape's test split (paper's seconds beside),
    windows per second at batch 256 and latency at batch 1; the exact rule last."""
    setup = inference.get("setup", {})
    headers = ["model", "variant", *(f"{s}: test split s (paper s)" for s in shapes),
               f"windows/s (batch {setup.get('batch', '?')})", "latency batch 1 (ms)", "file size (kB)"]
    table = Table("Table 4: inference time, ours (stated workload) beside the paper's seconds", headers)
    order = [m for m in TABLE4 if "_" not in m]  # the paper's row order, then any other model
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
                paper = _paper(model, variant, shape)
                text = f"{ours:.4f}" if ours is not None else "-"
                cells.append(f"{text} ({paper:g})" if paper is not None else f"{text} (-)")
            size = entry.get(f"{variant.split('_')[0]}_file_bytes")
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
        + f") in batches of {setup.get('batch', '?')}, median of {setup.get('repeats', '?')} interleaved repetitions, "
        f"{setup.get('torch_threads', '?')} torch threads on {setup.get('cpu', '?')} "
        f"({setup.get('cores', '?')} cores), "
        f"torch {setup.get('torch', '?')}. The paper's seconds are for a workload it does not state, on a GPU: "
        "compare orderings, not sizes.",
        "The eager INT8 graph simulates INT8 arithmetic in float (dequantize -> op -> quantize), so it is slower than "
        "FP32 by construction; INT8 kernels run only in the compiled graph.",
    ]
    return table
