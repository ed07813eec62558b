"""``toolpath smooth IN -o OUT``: a rough G-code program in, a smoother one out (Sec. 5.3), within a
two-sided tolerance, with nothing else changed.

It reads the program, cuts its feed moves into 50-point windows, classifies each (the exact
LocalCurvature rule by default, a trained FP32 ``.pt`` / INT8 ``.pt2`` model, or an ``.onnx`` file of the
qat stage run in ONNX Runtime or OpenVINO, ``--runtime``), smooths the rough
ones with the method their category maps to (mean filter, Bezier fit, NACOA; ``--method`` forces one)
and rewrites the X/Y numbers of the moved G1 lines only (:mod:`toolpath.smooth.rewrite`).  The
output is written to a temporary file and renamed; the input is never overwritten unless
``--in-place``, which first keeps it as ``IN.bak``.  ``--arcs`` also replaces runs of G1 lines by
one G2/G3 where an arc lies within the tolerance (:mod:`toolpath.smooth.arc_weld`).  Problems in
the input stop with ``FILE:LINE: message`` and exit code 1; wrong options with exit code 2.

The smoothing settings and machine limits are the pipeline's defaults (``params.yaml``: ``optimize``
and ``feedrate``), repeated here so the command runs outside the repository; a test keeps them equal.
"""

from __future__ import annotations

import argparse
import os
import shutil
import sys
from pathlib import Path

import numpy as np

#: ``optimize`` settings of params.yaml the command smooths with (tolerance and mode are its own)
SMOOTHING = {
    "penalty_weight": 10.0, "box": 0.25, "mean_filter": {"width": 5, "passes": 3}, "bezier": {"degree": 5},
    "nacoa": {"population": 30, "generations": 50, "hba_generations": 5, "alpha1": 2.0, "beta": 6.0, "alpha_max": 1.0,
              "alpha_min": 0.1, "m0": 10, "m_min": 2, "m_max": 10, "exchange_every": 10, "eta0": 0.01,
              "decay": 0.02, "gradient": "exact", "eps": 1.0e-05, "init": "perturb", "normalise": "point"},
}
DISPATCH = {2: "mean_filter", 3: "bezier", 4: "nacoa"}
#: ``feedrate.machine`` and ``feedrate.blend_tolerance`` of params.yaml: the machining-time estimate
MACHINE = {"feed": 100.0, "period": 0.001, "chord_error": 0.001, "contour_error": 0.005,
           "normal_acceleration": 2000.0, "normal_jerk": 50000.0, "tangential_acceleration": 2000.0,
           "tangential_jerk": 50000.0, "kp": 400.0, "inertia": 0.01, "damping": 1.0}
BLEND_TOLERANCE = 0.005
METHODS = {"dispatch": "dispatch", "mean": "mean_filter", "mean_filter": "mean_filter", "bezier": "bezier",
           "nacoa": "nacoa", "none": "none"}


class UsageError(Exception):
    """A wrong option or path: exit code 2."""


class InputError(Exception):
    """A problem in what the command was given to read: exit code 1."""


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="toolpath smooth", description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("input", type=Path, help="the G-code program to smooth")
    p.add_argument("-o", "--output", type=Path, help="where to write the smoothed program (not the input)")
    p.add_argument("--in-place", action="store_true", help="rewrite the input itself, keeping it first as IN.bak")
    p.add_argument("--force", action="store_true", help="overwrite an existing output, report or plot file")
    p.add_argument("--force-backup", action="store_true",
                   help="with --in-place, replace an IN.bak that holds another program (never done otherwise)")
    p.add_argument("--tolerance", type=float, default=0.01,
                   help="largest two-sided distance (mm) between the new path and the old (default 0.01)")
    p.add_argument("--classifier", default="rule",
                   help="'rule' (exact LocalCurvature, default), a trained FP32 .pt (models/fp32/<model>/<shape>.pt), "
                        "an INT8 .pt2, a registered model (models:/toolpath-gear@best, from ./mlflow.db or "
                        "MLFLOW_TRACKING_URI), or an ONNX file (models/int8/<model>/<shape>.onnx) run in --runtime")
    p.add_argument("--runtime", default="onnxruntime", choices=("onnxruntime", "openvino"),
                   help="the runtime of an .onnx classifier (default onnxruntime: it keeps every INT8 model within "
                        "a point of FP32, where OpenVINO's INT8 ConvMixer loses 33-37; reports/metrics/inference.json "
                        "names the fastest safe runtime per model)")
    p.add_argument("--method", default="dispatch", choices=sorted(METHODS),
                   help="dispatch (category 2 mean, 3 Bezier, 4 NACOA: Sec. 5.3), one method for all rough windows, "
                        "or none: nothing smoothed (with --arcs: arcs alone, as ArcWelder)")
    p.add_argument("--report", type=Path, help="write a report: REPORT.json, or REPORT.html with the path drawn")
    p.add_argument("--plot", type=Path, help="draw the path before and after, rough windows marked: PLOT.png or .svg")
    p.add_argument("--units", choices=("mm", "inch"),
                   help="the units the control runs a program in that sets none (no G20 / G21): such a program is "
                        "refused without it (a control left in the other units would run every move 25.4x off)")
    p.add_argument("--dialect", choices=("linuxcnc", "fanuc", "grbl"), default="linuxcnc",
                   help="how the control reads what dialects disagree on (default linuxcnc): fanuc (Fanuc, Haas) "
                        "takes an O1234 line as a program number and refuses axis words without a decimal point "
                        "(its X4 counts least increments); grbl reads its $ system commands and ? ~ ! lines")
    p.add_argument("--whole-integer-words", action="store_true",
                   help="with --dialect fanuc: an axis word without a decimal point (X4) is whole units, as on a "
                        "control set to calculator-type decimal input or Mach3, instead of refused")
    p.add_argument("--seed", type=int, default=0, help="seed of NACOA's random search (same seed, same output)")
    p.add_argument("--arcs", action="store_true",
                   help="also replace runs of G1 lines by one G2/G3 where an arc lies within the tolerance")
    return p


#: what an option needs beyond the core install, and the extra that brings it
EXTRAS = {"matplotlib": "plot", "torch": "models", "sklearn": "models", "onnxruntime": "int8", "openvino": "int8",
          "mlflow": "registry"}
REGISTRY_SCHEMES = ("models:/", "runs:/")  # an MLflow model URI: models:/toolpath-gear@best


def _needs(args: argparse.Namespace) -> None:
    """Stop before any work, naming the extra to install, when an option needs a package the core install
    (NumPy and rich) does not bring: a plot or an HTML report (matplotlib), a trained classifier (torch,
    scikit-learn; an .onnx file its runtime)."""
    from importlib.util import find_spec

    wanted = []
    if args.plot is not None or (args.report is not None and args.report.suffix.lower() == ".html"):
        wanted.append(("matplotlib", "--plot and an HTML --report draw with matplotlib"))
    suffix = Path(args.classifier).suffix.lower()
    if args.classifier == "rule":
        pass
    elif args.classifier.startswith(REGISTRY_SCHEMES):
        wanted += [("mlflow", "a models:/ classifier is read from the MLflow registry"),
                   ("torch", "a trained classifier runs in torch")]
    elif suffix == ".onnx":
        wanted.append((args.runtime, f"an .onnx classifier runs in {args.runtime}"))
    else:
        wanted.append(("torch", "a trained classifier runs in torch"))
        if suffix != ".pt2":
            wanted.append(("sklearn", "a trained .pt classifier is a scikit-learn estimator"))
    for module, why in wanted:
        if find_spec(module) is None:
            raise UsageError(f"{why}, which is not installed: pip install 'toolpath-lab[{EXTRAS[module]}]'")


def _paths(args: argparse.Namespace):
    """The run's outputs (:func:`toolpath.smooth.outputs.plan`: checked against the input, each other and
    what is there) after the input and the file kinds are checked."""
    from toolpath.smooth.outputs import PathProblem, plan

    if not args.input.exists():
        raise UsageError(f"{args.input}: no such file")
    if not args.input.is_file():  # a folder, /dev/zero, a pipe: nothing with an end to read and back up
        raise UsageError(f"{args.input}: not a regular file")
    if args.report is not None and args.report.suffix.lower() not in (".json", ".html"):
        raise UsageError(f"{args.report}: a report is .json or .html")
    if args.plot is not None and args.plot.suffix.lower() not in (".png", ".svg"):
        raise UsageError(f"{args.plot}: a plot is .png or .svg")
    try:
        return plan(args.input, args.output, args.in_place, args.report, args.plot, args.force, args.force_backup)
    except PathProblem as exc:
        raise UsageError(str(exc)) from None


def checked(predict, spec: str):
    """``predict`` once it has classified a probe batch of two windows into two categories 1-4: a model
    file that is valid but no window classifier (another input shape, another output) is the file's
    problem, said in one line before any work."""
    probe = np.cumsum(np.full((2, 50, 2), 0.1), axis=1)  # two straight windows, relative to their first point
    try:
        got = np.asarray(predict(probe))
    except Exception as exc:  # noqa: BLE001 - whatever the runtime raises, the file does not fit
        reason = (str(exc).splitlines() or [type(exc).__name__])[0][:160]
        raise InputError(f"{spec}: not a classifier of 50-point windows ({reason})") from None
    if got.shape != (2,) or not np.isin(got, (1, 2, 3, 4)).all():
        raise InputError(f"{spec}: not a classifier of 50-point windows (it answered {got.tolist()!r} for two "
                         "windows, not two categories 1-4)")
    return predict


def classifier(spec: str, runtime: str = "onnxruntime"):
    """A function from windows (N, 50, 2) in mm, relative to their first point, to Table 1 categories 1-4."""
    if spec == "rule":  # Eq. 3 and Table 1 directly: the rule's estimator needs scikit-learn and torch to import
        from toolpath.geometry.curvature import local_curvature
        from toolpath.geometry.labels.categories import categorize

        return lambda X: categorize(local_curvature(np.asarray(X, np.float64))).astype(np.int64)
    if spec.startswith(REGISTRY_SCHEMES):
        return _registered(spec)
    path = Path(spec)
    if not path.is_file():
        raise UsageError(f"{spec}: no such model file (or say --classifier rule)")
    if path.suffix == ".onnx":
        from toolpath.inference import runtimes

        try:
            run = runtimes.runner(path, runtime, threads=max(1, min(os.cpu_count() or 1, 4)))
        except Exception as exc:  # noqa: BLE001 - any failure to load is the file's problem, said in one line
            reason = (str(exc).splitlines() or [type(exc).__name__])[0][:160]
            raise InputError(f"{path}: not a model {runtime} can run ({reason})") from None
        return lambda X: runtimes.logits(run, X).argmax(1) + 1

    if path.suffix == ".pt2":
        from toolpath.inference.qat import load

        try:
            network = load(path)
        except Exception as exc:  # noqa: BLE001 - any failure to load is the file's problem, said in one line
            reason = (str(exc).splitlines() or [type(exc).__name__])[0][:160]
            raise InputError(f"{path}: not a readable INT8 model ({reason})") from None
    else:
        from toolpath.pipeline.artifacts import load_classifier

        try:
            model = load_classifier(path, "train")
        except SystemExit as exc:  # ArtifactError: its message names a pipeline stage, not this command
            problem = getattr(exc, "problem", str(exc))
            raise InputError(f"{path}: not a readable model checkpoint ({problem[:160]})") from None
        return lambda X: np.asarray(model.predict(np.asarray(X, np.float32)))
    return _predictor(network)


def _predictor(network):
    """Categories 1-4 from a torch network's four logits."""
    import torch

    from toolpath.models.training.loop import predict_logits

    def predict(X: np.ndarray) -> np.ndarray:
        logits = predict_logits(network, torch.as_tensor(np.asarray(X, np.float32)))
        return logits.argmax(1).numpy() + 1

    return predict


def _registered(uri: str):
    """Categories 1-4 by the network an MLflow model URI names, from ``MLFLOW_TRACKING_URI`` or else the
    pipeline's store (``mlflow.db`` in the current folder, as ``make repro`` writes it).  MLflow keeps it
    as an exported graph, already in eval mode (it has no ``eval()``)."""
    import logging

    import mlflow
    import torch

    logging.getLogger("mlflow").setLevel(logging.ERROR)  # its store-migration chatter is no news to a machinist
    store = os.environ.get("MLFLOW_TRACKING_URI") or f"sqlite:///{Path.cwd() / 'mlflow.db'}"
    mlflow.set_tracking_uri(store)
    mlflow.set_registry_uri(store)
    try:
        network = mlflow.pytorch.load_model(uri, map_location="cpu")
    except Exception as exc:  # noqa: BLE001 - an unknown name, alias or store is the URI's problem, in one line
        reason = (str(exc).splitlines() or [type(exc).__name__])[0][:200]
        raise InputError(f"{uri}: no model to load from the MLflow store {store} ({reason})") from None

    def predict(X: np.ndarray) -> np.ndarray:
        X = torch.as_tensor(np.asarray(X, np.float32))
        with torch.no_grad():
            logits = [network(X[i:i + 1024]) for i in range(0, len(X), 1024)]
        return torch.cat(logits).argmax(1).numpy() + 1 if logits else np.zeros(0, np.int64)

    return predict


def machining_time(runs_before: list[np.ndarray], runs_after: list[np.ndarray]) -> tuple:
    """Seconds the feed planner needs for every feed run before and after, under :data:`MACHINE`
    (:func:`toolpath.feedrate.timing.machining_time`; a run the rewrite left alone is planned once);
    (None, None, why) when a run cannot be planned."""
    from toolpath.feedrate import Machine
    from toolpath.feedrate.timing import machining_time as seconds

    machine, before, after = Machine(**MACHINE), 0.0, 0.0
    try:
        for old, new in zip(runs_before, runs_after, strict=True):
            t = seconds(old, machine, BLEND_TOLERANCE)
            before += t
            after += t if np.array_equal(old, new) else seconds(new, machine, BLEND_TOLERANCE)
    except ValueError as exc:
        return None, None, str(exc)
    return before, after, None


def _progress(items: list) -> list:
    if not sys.stderr.isatty() or len(items) < 2:
        return items
    from rich.progress import track

    return track(items, description="smoothing", console=None, transient=True)


def run(args: argparse.Namespace) -> dict:
    from toolpath.gcode import GCodeError, ReaderOptions
    from toolpath.smooth.outputs import atomic
    from toolpath.smooth.report import summary, write_plot, write_report
    from toolpath.smooth.rewrite import RewriteOptions
    from toolpath.smooth.stream import ARC_PART_BYTES, PART_BYTES, Combined, smooth_parts

    if not (np.isfinite(args.tolerance) and args.tolerance > 0):
        raise UsageError(f"--tolerance {args.tolerance}: must be a positive number of mm")
    if not 0 <= args.seed < 2**32:
        raise UsageError(f"--seed {args.seed}: must be a whole number from 0 to 4294967295")
    outputs = _paths(args)
    _needs(args)
    predict = checked(classifier(args.classifier, args.runtime), args.classifier)
    options = RewriteOptions(tolerance=args.tolerance, smoothing=SMOOTHING, method=METHODS[args.method],
                             mapping=DISPATCH, seed=args.seed)
    drawn = args.plot is not None or (args.report is not None and args.report.suffix.lower() == ".html")
    total = Combined(keep_paths=drawn)
    with atomic(outputs.program) as out:  # renamed into place last, when every other file is written
        try:
            units = None
            # what the tool does not smooth (other planes' arcs, cycles, compensation, probing, O-words) is
            # read past and copied through as written (toolpath.gcode.passing)
            reading = ReaderOptions(pass_through=True, dialect=args.dialect,
                                    whole_integer_words=args.whole_integer_words)
            part_bytes = ARC_PART_BYTES if args.arcs else PART_BYTES
            for part in smooth_parts(args.input, predict, options, reading, part_bytes, progress=_progress,
                                     units=args.units):
                units = part.program.units
                if args.arcs:
                    _weld(part.result, part.program, args.tolerance, part.start, args.report is not None or drawn)
                out.write(part.result.text.encode("utf-8", errors="surrogateescape"))  # undecodable bytes kept
                # the machining time is in the report only: without one, the planner is not run
                total.add(part, machining_time(part.result.runs_before, part.result.runs_after)
                          if args.report is not None else (None, None, "no --report asked for"))
        except GCodeError as exc:
            raise InputError(str(exc)) from None
        if units is not None and "no unit word" in units and args.units is None:
            raise UsageError(f"{args.input}: the program sets no units (no G20 / G21): pass --units mm or "
                             "--units inch, the units its control runs it in")
        report = summary(args, total.lines, total, (total.before, total.after, total.why), MACHINE)
        unset = units is not None and "no unit word" in units
        report["units"] = {"set_by_program": None if unset else units, "assumed": args.units if unset else None}
        if outputs.backup is not None:  # copied in blocks: a 10-million-line program never sits in memory
            with atomic(outputs.backup) as copy, args.input.open("rb") as original:
                shutil.copyfileobj(original, copy, 1 << 20)
        if outputs.report is not None:
            with atomic(outputs.report) as fh:
                write_report(fh, outputs.report.suffix.lower(), report, total)
        if outputs.plot is not None:
            with atomic(outputs.plot) as fh:
                write_plot(fh, outputs.plot.suffix.lower(), total)
    return report


def _weld(result, program, tolerance: float, start, paths: bool = True) -> None:
    """``--arcs``: G1 runs of the smoothed part (a part the smoothing left as it was: as read, not read again)
    replaced by arcs (:mod:`toolpath.smooth.arc_weld`); with ``paths`` (a report plans the machining time, a
    plot draws them) the runs as a controller runs them."""
    from dataclasses import replace

    from toolpath.geometry.labels.windows import feed_runs
    from toolpath.smooth.arc_runs import text_of
    from toolpath.smooth.arc_weld import weld_arcs

    smoothed = program if result.text == text_of(program) else start.snapshot().read(result.text)
    text, arcs, lines, note, kept_as_lines = weld_arcs(smoothed, program, tolerance, start=start)
    result.text, result.arcs, result.arcs_note, result.arcs_kept_as_lines = text, arcs, note, kept_as_lines
    # the feed planner sees an arc as chords within its blend tolerance (finer chords only add vertices)
    if paths:
        coarse = start.with_options(replace(start.options, chord_tolerance=BLEND_TOLERANCE))
        result.runs_after = [xy for xy, _ in feed_runs(coarse.read(text))]
    else:  # nothing reads them: not the runs of the text before the arcs either
        result.runs_after = []
    result.changed_lines = lines if not len(result.changed_lines) else \
        np.union1d(np.asarray(result.changed_lines, np.int64), lines)


SIGNAL_EXITS = {"SIGINT": (130, "interrupted"), "SIGTERM": (143, "terminated")}


def _stop(signum, frame) -> None:
    """SIGINT / SIGTERM: remove the temporaries and exit at once.  An exception raised here could land
    in a finaliser, where Python prints and swallows it and the run goes on (seen once in the suite);
    nothing is renamed over an input after this point, so the input stays as it was."""
    import signal

    from toolpath.smooth.outputs import remove_pending

    code, said = SIGNAL_EXITS[signal.Signals(signum).name]
    remove_pending()
    sys.stderr.write(f"toolpath smooth: {said}, no file written\n")
    sys.stderr.flush()
    os._exit(code)


def main(argv: list[str] | None = None) -> int:
    import signal

    p = parser()
    args = p.parse_args(argv)
    previous = {signum: signal.signal(signum, _stop) for signum in (signal.SIGINT, signal.SIGTERM)}
    try:
        report = run(args)
    except KeyboardInterrupt:  # a SIGINT before the handler was set: the input untouched, no temporary left
        print("toolpath smooth: interrupted, no file written", file=sys.stderr)
        return 130
    except UsageError as exc:
        p.print_usage(sys.stderr)
        print(f"toolpath smooth: error: {exc}", file=sys.stderr)
        return 2
    except InputError as exc:
        print(f"toolpath smooth: {exc}", file=sys.stderr)
        return 1
    except OSError as exc:
        print(f"toolpath smooth: {exc.filename or ''}: {exc.strerror}", file=sys.stderr)
        return 1
    except Exception as exc:  # noqa: BLE001 - a user gets one line, never a traceback; the output is not written
        print(f"toolpath smooth: internal error, no file written: {type(exc).__name__}: {exc}", file=sys.stderr)
        return 3
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler)
    w = report["windows"]
    print(f"{args.input} -> {report['output']}: {w['total']} windows ({w['smoothed']} smoothed), "
          f"{report['lines_changed']} lines changed, largest deviation {report['largest_deviation_mm']:.4f} mm "
          f"(tolerance {args.tolerance} mm)" + (f", {report['arcs']['fitted']} arcs replacing "
                                                f"{report['arcs']['lines_replaced']} G1 lines" if args.arcs else "")
          + (f"; passed through as written: {'; '.join(report['passed_through'][:3])}"
             + (f" and {len(report['passed_through']) - 3} more" if len(report["passed_through"]) > 3 else "")
             if report["passed_through"] else ""), file=sys.stderr)
    return 0
