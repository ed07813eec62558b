"""What a warm start saves a stage: one stage run in its own process and handed to the warm server of
``make repro`` (:mod:`toolpath.pipeline.warm`), alternately, in one run (the ratio is side by side).

The stage is ``generate@gear`` of the smoke profile (4 programs) in a scratch folder holding ``conf/`` and
the composed ``params.yaml``, with its own MLflow store: a stage whose work is small, so the difference is
the start-up and teardown every stage of ``dvc repro`` pays.  The first run of each kind is a warm-up
(the server's preload, the kernels' compile caches) and is not counted.
"""

from __future__ import annotations

import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from toolpath.pipeline import config, warm

STAGE = ("generate", "--shape", "gear")


def bench_warm_start(root: Path, repeats: int = 3) -> dict:
    """Seconds per run of :data:`STAGE` started cold and handed to a warm server (medians of ``repeats``)."""
    with tempfile.TemporaryDirectory(prefix="toolpath-bench-warm-") as folder:
        work = Path(folder) / "repo"
        shutil.copytree(root / "conf", work / "conf")
        config.compose(["+experiment=smoke"], root=work)
        socket_path = Path(folder) / "s.sock"
        env = {k: v for k, v in os.environ.items() if k != warm.SOCKET_ENV}
        env["MLFLOW_TRACKING_URI"] = f"sqlite:///{folder}/mlflow.db"
        server = subprocess.Popen([sys.executable, "-m", warm.MODULE, "--serve", str(socket_path)],
                                  start_new_session=True, stdout=subprocess.DEVNULL)
        try:
            while not socket_path.exists():
                if server.poll() is not None:
                    raise RuntimeError("the warm server did not start")
                time.sleep(0.02)
            command = [sys.executable, "-m", f"toolpath.stages.{STAGE[0]}", *STAGE[1:]]
            seconds: dict[str, list[float]] = {"cold": [], "warm": []}
            for _ in range(repeats + 1):
                for kind, run_env in (("cold", env), ("warm", {**env, warm.SOCKET_ENV: str(socket_path)})):
                    start = time.perf_counter()
                    subprocess.run(command, cwd=work, env=run_env, check=True, capture_output=True)
                    seconds[kind].append(time.perf_counter() - start)
        finally:
            server.terminate()
            server.wait(10)
    cold, hot = (statistics.median(seconds[k][1:]) for k in ("cold", "warm"))
    return {"stage": f"{STAGE[0]}@{STAGE[2]} (smoke profile)", "repeats": repeats,
            "cold_s": seconds["cold"][1:], "warm_s": seconds["warm"][1:], "cold_median_s": cold,
            "warm_median_s": hot, "saved_s_per_stage": cold - hot, "speedup": cold / hot}
