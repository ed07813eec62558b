"""Assembling ``reports/report.md`` from sections, and the README block the report stage rewrites.

A :class:`Section` either has a Markdown body or names the inputs it is missing and the stage that
writes them, so a report built before every stage has run says what is absent instead of failing.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

README_BEGIN = ("<!-- report:begin (written by `make readme` from reports/readme_block.md; edits here are "
                "overwritten) -->")
README_END = "<!-- report:end -->"

# Every interpretation the pipeline makes of the paper, with where it is configured or explained.
DIFFERENCES = (
    "**Data.** The paper's G-code data set was never published. Our gear, pentagram-boss and maple-leaf programs "
    "are synthesised (`toolpath.shapes`): CAM-like offsets, chordal discretisation and the artefacts real output "
    "has (tiny segments, normal noise, rounding), every value drawn from `conf/generate` and recorded in each "
    "program's header. Windows are split by program, so no program is in two splits.",
    "**Model input.** The paper says MCRL learns from the input coordinates. Our default input (`inputs: turning` in "
    "`conf/model/*.yaml`) is, per point, the turning terms of Eq. 1-3 (1 - cos, sin): on coordinates none of our "
    "networks beat the majority class in the default profile's epochs. `inputs: coordinates` runs the paper's input.",
    "**MCRL (Sec. 5.1.1).** The attention, the resampling of each branch (50 / 30 / 20 / 10 points), how a branch "
    "passes its output to the next and the linear fusion of the four heads are our reading of a text that gives "
    "no equations for them (`toolpath.models.mcrl`). A branch resamples by averaging each output point's share of "
    "the input (`resample: area`), so every turning term reaches it; interpolating (`resample: linear`) reads 20 "
    "of the 50 points at 10 and drops a turn between them.",
    "**Training.** `+experiment=paper` runs Table 2 as printed (staircase decay, 203-497 epochs at 1e-4 / 5e-4). "
    "The default profile aims at the pipeline's time budget with a schedule scaled to the steps it runs: one-cycle "
    "warm-up and cosine decay (`train.common.schedule`) to a peak learning rate of its own "
    "(`train.per_shape.<shape>.lr`), "
    "gradient clipping (`train.common.clip_grad_norm`), the best-validation epoch's weights and one batch size "
    "on every shape (Table 2: 32 on the pentagram); every learned model then trains under one protocol "
    "(`train.protocol`, below). Every input feature is scaled to unit RMS over the training windows "
    "(`train.common.normalise_inputs`). Every model trains `train.replicates` times with its own seed and Table 3 "
    "gives mean +- sd; the paper reports one run. MCRL (`conf/model/mcrl_fused.yaml`) fuses each branch with "
    "the previous branch's 4-class output (our reading of \"fused with the ... output\"; the hidden-vector "
    "reading is `fuse: hidden`), trains an auxiliary cross-entropy on each branch's head, which the paper does "
    "not have (chosen on validation in the protocol's study); its own `schedule` (hand trials scored on gear's "
    "test programs, its header) is kept for runs outside the protocol and no longer decides Table 3; the "
    "Optuna winner of "
    "`conf/sweep/mcrl.yaml` "
    "(`conf/model/mcrl_tuned.yaml`, selected on 6 gear validation programs) did not hold on 39-81 test programs. "
    "Half of each shape's programs are test programs. The exact LocalCurvature rule is scored on the same test "
    "programs: it is the ceiling.",
    "**Two inputs (Table 3a / 3b).** Table 3a feeds every architecture the paper's input, the window's 50 x 2 "
    "coordinates moved to their centroid and scaled to unit RMS radius (no rotation), through learned first "
    "layers of our design (`toolpath.models.inputs.DifferenceStem`: a convolution whose kernel sums to zero over "
    "each segment, each segment's channel vector scaled to unit RMS, a second zero-sum convolution, GELU, back "
    "to 2 channels); without the stem every model stayed at the majority class, and so did the CNN (one "
    "trial on gear) with the stem but without the per-segment normalisation. "
    "Table 3b feeds the per-point turning terms (1 - cos, sin), whose first channel summed over the window is "
    "LocalCurvature. Every learned model of both blocks trains under one protocol (`train.protocol`: the same "
    "epochs, batch, schedule, augmentation and class weighting; each learning rate, and MCRL's auxiliary heads, "
    "chosen from one grid on gear's validation programs, `python -m toolpath.sweep.protocol`, the test split "
    "never read). A logistic regression on each flattened input shows what the input alone "
    "gives. Table 3c gives MCRL minus every model with a paired interval over test programs and seeds.",
    "**Baselines.** ConvMixer, ConvNeXt and MaxViT are our 1-D adaptations of image models, sized within a factor "
    "of 2 of MCRL's parameters; ConvMixer and MaxViT embed 5 points per token (`patch: 5`), half the time per "
    "epoch of 2-point tokens at the same parameter count.",
    "**QAT and Table 4.** PT2E quantization-aware training with torchao's x86 quantizer over the whole training "
    "split; only `Linear` layers run INT8, and the input normalisation and the layers that see the raw turning "
    "terms stay float (`qat.float_modules`, listed per model in `reports/metrics/qat/`). Table 4's workload is "
    "ours (each test split); the paper's seconds have no stated workload.",
    "**NACOA.** The paper's initialisation permutes the interior points (Sec. 4.2.1), which scrambles the order "
    "the path visits them: it runs as `nacoa_permute`; the default starts from the original window. Eq. 5 is run "
    "in displacement space with a capped intensity, Eq. 12's random term is scaled by the tolerance, Eq. 25's step "
    "is normalised per point; Eq. 23's central difference is available beside the exact gradient.",
    "**Eq. 34.** Efficiency leaves 'theoretical optimal' and 'actual' resource usage undefined: ours is the "
    "Fitness reduction per second, not comparable with the paper's 8.4.",
    "**Fidelity.** The paper bounds nothing: its smoothed paths may leave the part. Every method also runs in "
    "`bound` mode (the smoothed window and the original within 0.05 mm of each other both ways: the exact "
    "two-sided distance), and every table gives that deviation.",
    "**Table 6.** Our times are CPU seconds per window at NACOA's evaluation budget; the paper's are GPU minutes "
    "for an unstated workload. The mealpy baselines also run on a shifted encoding, because CoatiOA and ESOA are "
    "drawn to the origin of the search space, which here is the original path.",
)


@dataclass
class Section:
    """One part of the report: a title and a Markdown body, or the inputs it lacks."""

    title: str
    body: str = ""
    missing: list[str] = field(default_factory=list)
    stage: str = ""

    def markdown(self) -> str:
        if self.missing:
            files = ", ".join(f"`{m}`" for m in self.missing)
            hint = f"; run `dvc repro {self.stage}`" if self.stage else ""
            return f"## {self.title}\n\n**Missing section**: needs {files}{hint}.\n"
        return f"## {self.title}\n\n{self.body.rstrip()}\n"


def report_markdown(sections: Sequence[Section], profile: str, commit: str, clean: bool | None) -> str:
    """The whole report: provenance, contents, the sections, the differences from the paper."""
    missing = [s.title for s in sections if s.missing]
    source = {True: "clean source tree", False: "source tree with uncommitted changes",
              None: "source state unknown: git unavailable"}[clean]
    lines = ["# toolpath-lab report: Li et al. (Sensors 2024) regenerated beside the paper", "",
             f"Profile `{profile}`, git commit `{commit}` ({source}). Generated by `dvc repro report` from the "
             "pipeline's DVC outputs only; every number below is read from them, none is typed in. "
             "Regenerate everything with `make repro`.", ""]
    if missing:
        lines += ["**Missing sections**: " + "; ".join(missing) + ".", ""]
    lines += ["Contents: " + " · ".join(s.title for s in sections) + " · Differences from the paper", ""]
    lines += [s.markdown() for s in sections]
    lines += ["## Differences from the paper", "", *(f"* {d}" for d in DIFFERENCES), ""]
    return "\n".join(lines)


def replace_block(text: str, block: str, name: str = "README.md", marker: str = "report") -> str:
    """``text`` with everything between the ``marker`` block's lines (``<!-- report:begin ...-->`` and
    ``<!-- report:end -->`` for the report's) replaced by ``block``."""
    begin_line = README_BEGIN if marker == "report" else f"<!-- {marker}:begin"
    end_line = README_END if marker == "report" else f"<!-- {marker}:end -->"
    begin, end = text.find(begin_line), text.find(end_line)
    if begin < 0 or end < begin:
        raise ValueError(f"{name}: {marker} markers not found (a line '{begin_line}' followed by '{end_line}')")
    opened = text.index("\n", begin) if marker != "report" else begin + len(README_BEGIN)
    return text[:opened] + "\n" + block.rstrip() + "\n" + text[end:]
