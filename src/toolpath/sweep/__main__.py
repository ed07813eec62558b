"""Budgeted Bayesian search (Optuna TPE, seeded) over a model's hyperparameters.

Run from the repository root, after `dvc repro generate@<shape>`:

    python -m toolpath.sweep                                   # conf/sweep/mcrl.yaml as it stands
    python -m toolpath.sweep sweep.n_trials=40 sweep.workers=2 train.per_shape.gear.epochs=20
    python -m toolpath.sweep --config mcrl +experiment=smoke   # any Hydra override of conf/
    python -m toolpath.sweep --trials 5                        # exactly 5 more trials (one machine of several)

The study lives in ``sweep.storage`` (``sqlite:///optuna.db``, or ``TOOLPATH_SWEEP_STORAGE``): run the
same command again and a stopped sweep resumes, running the trials still missing from ``n_trials``.
"""

from __future__ import annotations

import argparse
import sys
import time
from concurrent.futures import ProcessPoolExecutor, wait
from multiprocessing import get_context
from pathlib import Path

import optuna

from toolpath.sweep.study import SweepSpec


def _parse(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog="python -m toolpath.sweep", description=__doc__.split("\n")[0])
    parser.add_argument("--config", default="mcrl", help="conf/sweep/<CONFIG>.yaml (default: mcrl)")
    parser.add_argument("--trials", type=int, default=None,
                        help="run exactly this many trials now, whatever the study holds (default: the "
                             "trials still missing from sweep.n_trials)")
    parser.add_argument("--adopt", action="store_true",
                        help="also copy the tuned config into conf/model/ (a sweep writes into conf/ only when asked), "
                             "so `dvc exp run -S model@models.<model>=<model>_tuned` can use it")
    parser.add_argument("overrides", nargs="*", help="Hydra overrides of conf/ (sweep.*, train.*, +experiment=...)")
    return parser.parse_args(argv)


def _shares(total: int, workers: int) -> list[int]:
    """``total`` trials split as evenly as possible over at most ``workers`` processes."""
    workers = max(1, min(workers, total))
    return [total // workers + (k < total % workers) for k in range(workers)] if total else []


def _run(spec: SweepSpec, study: optuna.Study, shares: list[int]) -> None:
    """Run the shares, the first in this process and each other in a spawned one (a process less to start
    and import torch in), under a progress bar over the study; each process samples with its own seed
    (:func:`toolpath.sweep.study.claim_workers`)."""
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

    from toolpath.sweep.study import claim_workers, run_trials

    first = claim_workers(spec, study, len(shares))

    finished = (optuna.trial.TrialState.COMPLETE, optuna.trial.TrialState.FAIL)
    start = len(study.get_trials(states=finished))
    columns = (TextColumn(f"sweep {spec.study}"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(),
               TextColumn("{task.fields[best]}"))
    with Progress(*columns) as bar:
        task = bar.add_task("trials", total=sum(shares), best="")

        def refresh(*_: object) -> None:  # from the study, which every process of the launch writes
            done = study.get_trials(states=finished)
            values = [t.value for t in done if t.value is not None]
            bar.update(task, completed=len(done) - start, best=f"best {max(values):.4f}" if values else "")

        # a spawned worker waits for this process to take the enqueued default trial; with one share alone the
        # launch is deterministic for a seed
        with ProcessPoolExecutor(max(1, len(shares) - 1), mp_context=get_context("spawn")) as pool:
            futures = [pool.submit(run_trials, spec, n, first + k, (), False)
                       for k, n in enumerate(shares[1:], start=1)]
            run_trials(spec, shares[0], worker=first, callbacks=[refresh])
            while wait(futures, timeout=2.0).not_done:  # back as soon as the last worker ends
                refresh()
            for f in futures:
                f.result()  # a worker's error surfaces here
        bar.update(task, completed=sum(shares))


def main(argv: list[str] | None = None) -> int:
    args = _parse(argv)
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    root = Path.cwd()
    if not (root / "conf" / "sweep" / f"{args.config}.yaml").is_file():
        print(f"error: conf/sweep/{args.config}.yaml not found (run from the repository root)", file=sys.stderr)
        return 2
    try:
        from toolpath.sweep.finish import finish
        from toolpath.sweep.study import base_config as compose
        from toolpath.sweep.study import open_study, spec_from

        base_overrides = [f"+sweep={args.config}", *args.overrides]
        base = compose(root, base_overrides)
        # search from the model's own config, not the tuned one the defaults may pick: a tuned schedule
        # would override the very keys the search samples
        choice = f"model@models.{base.sweep.model}="
        if base.sweep.model in base.models and not any(o.startswith(choice) for o in args.overrides):
            base_overrides.append(f"{choice}{base.sweep.model}")
            base = compose(root, base_overrides)
        from toolpath.pipeline.config import validate

        validate(base, root, "the sweep's configuration")  # a bad base override stops before any trial
        spec = spec_from(base, root, base_overrides)
        windows = Path(str(base.paths.windows)) / f"{spec.shape}.npz"
        if not (root / windows).is_file():
            raise FileNotFoundError(f"{windows} not found: run `dvc repro generate@{spec.shape}` first")
        study = open_study(spec)
        complete = len(study.get_trials(states=(optuna.trial.TrialState.COMPLETE,)))
        todo = args.trials if args.trials is not None else max(0, spec.n_trials - complete)
        print(f"sweep {spec.study}: {complete} trials complete in {spec.storage.split('@')[-1]}; "
              f"running {todo} with {min(spec.workers, max(todo, 1))} worker(s)")
        start = time.perf_counter()
        if todo:
            _run(spec, study, _shares(todo, spec.workers))
        summary = finish(spec, study, seconds=time.perf_counter() - start)
    except (ValueError, KeyError, FileNotFoundError, RuntimeError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:  # Ctrl-C: the study keeps what finished, and the same command resumes it
        print("sweep stopped: every finished trial is kept in the study; run the same command again to go on",
              file=sys.stderr)
        return 130
    except SystemExit as exc:  # toolpath.pipeline.schema.ConfigError: one line naming the key
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except Exception as exc:  # Hydra's config errors name the override or file at fault
        if type(exc).__module__.startswith(("hydra", "omegaconf")):
            print(f"error: {' '.join(str(exc).split())}", file=sys.stderr)
            return 2
        raise
    best, default = summary["best"], summary["default"]
    print(f"best trial {best['number']}: {spec.objective} {best['value']:.4f}"
          + (f" (default configuration, trial {default['number']}: {default['value']:.4f})" if default else ""))
    print(f"wrote {summary['tuned_config']}, {spec.summary.relative_to(root)}, "
          + ", ".join(v for v in summary["figures"].values()))
    if args.adopt:
        adopted = root / "conf" / "model" / Path(summary["tuned_config"]).name
        adopted.write_text((root / summary["tuned_config"]).read_text(encoding="utf-8"), encoding="utf-8")
        print(f"adopted it as {adopted.relative_to(root)}: dvc exp run -S 'model@models.{spec.model}={adopted.stem}'")
    return 0


if __name__ == "__main__":
    sys.exit(main())
