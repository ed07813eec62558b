"""What a warm start saves a stage: one stage run in its own process and handed to the warm server of
``make repro`` (:mod:`toolpath.pipeline.warm`), alternately, in one run (the ratio is side by side).

The stage is ``generate@gear`` of the smoke profile (4 programs) in a scratch folder holding ``conf/`` and
the composed ``params.yaml``, with its own MLflow store: a stage whose work is small, so the difference is
the start-up and teardown every stage of ``dvc repro`` pays.  The first run of each kind is a warm-up
(the server's preload, the kernels' compile caches) and is not counted.  Beside it, the same training steps
timed inside a spawned worker and inside a worker the server forks (:func:`training_steps`): whether a forked
worker computes as fast.
"""

from __future__ import annotations

import multiprocessing
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

from toolpath.pipeline import config, warm
from toolpath.pipeline.warm_pool import WarmPool

STAGE = ("generate", "--shape", "gear")
TRAINING_STEPS = 40  # MCRL steps on a batch of 64 random windows, one torch thread (about 5 s)


def training_steps(seed: int) -> float:
    """Seconds of :data:`TRAINING_STEPS` MCRL training steps in this process (its start-up not counted)."""
    import torch

    from toolpath.models.mcrl import MCRL

    torch.set_num_threads(1)
    torch.manual_seed(seed)
    net = MCRL(fuse="output")
    optimiser = torch.optim.Adam(net.parameters(), 1e-3)
    x, y = torch.randn(64, 50, 2).cumsum(dim=1), torch.randint(0, 4, (64,))
    start = time.perf_counter()
    for _ in range(TRAINING_STEPS):
        optimiser.zero_grad()
        torch.nn.functional.cross_entropy(net(x), y).backward()
        optimiser.step()
    return time.perf_counter() - start


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
            # the same work in a spawned worker and in one the warm server forks: is a forked worker's compute slower?
            steps: dict[str, list[float]] = {"spawned": [], "forked": []}
            for seed in range(repeats):
                with ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn")) as pool:
                    steps["spawned"].append(pool.submit(training_steps, seed).result())
                with WarmPool(socket_path, 1) as pool:
                    steps["forked"].append(pool.submit(training_steps, seed).result())
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
            "warm_median_s": hot, "saved_s_per_stage": cold - hot, "speedup": cold / hot,
            "training_steps": {"steps": TRAINING_STEPS, "spawned_s": steps["spawned"], "forked_s": steps["forked"],
                               "forked_vs_spawned": statistics.median(steps["forked"]) /
                               statistics.median(steps["spawned"])}}
