"""Warm starts for DVC stages: the pipeline's libraries imported once, every stage forked from them.

Run: python -m toolpath.pipeline.warm -- dvc repro      (``make repro`` does)

A stage's own work is a few seconds in the smoke profile and often under a minute in the default one,
while a fresh interpreter spends about 7 s of it importing torch, scikit-learn, SciPy and MLflow
(``python -X importtime -m toolpath.stages.classify``).  This wrapper starts a server in its own
session, listening on a Unix socket in a private temporary folder named by :data:`SOCKET_ENV` in the
command's environment, which imports what the stage modules import (:func:`preload`) and then drops
every ``toolpath`` module again, so stages run the code on disk and only third-party libraries come
from it.  A stage started as ``python -m toolpath.stages.<name>`` (``toolpath.stages`` calls
:func:`hand_over_stage` on import) connects and passes its stdin, stdout and stderr, arguments, working
folder and environment; the server forks a watcher, the watcher forks the runner, which runs the stage
module as ``python -m`` would (``sys.path[0]`` the working folder); the watcher sends the runner's exit
status and the stage's process exits with it, forwarding SIGINT / SIGTERM / SIGHUP to the runner
meanwhile.  :data:`STAGE_PID_ENV` names the stage's own process to the runner, so its MLflow run starts
when that process started and finds its ``dvc`` parent (:mod:`~toolpath.pipeline.tracking`).

With no server (a plain ``dvc repro`` or ``dvc exp run``, a queue worker), one another interpreter or
checkout started, or one that is gone, the stage runs in its own process as before.  Outputs are the
same bytes either way: every stage seeds its own generators (``tests/test_warm.py`` compares a stage's
outputs run both ways).
"""

from __future__ import annotations

import argparse
import contextlib
import gc
import json
import os
import selectors
import signal
import socket
import struct
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

SOCKET_ENV = "TOOLPATH_WARM_SOCKET"
POOL_ENV = "TOOLPATH_WARM_POOL"  # set in a runner: the server its stage's process pools fork workers from
STAGE_PID_ENV = "TOOLPATH_STAGE_PID"  # set in a runner: the pid of the stage's process as DVC started it
STAGES = "toolpath.stages."
MODULE = "toolpath.pipeline.warm"  # this module's name (``__name__`` is ``__main__`` when it runs as the wrapper)
# imported lazily by the stages (inside functions), so importing the stage modules does not load them;
# torch._inductor: torch.use_deterministic_algorithms imports it (2.7 s) in the qat, benchmark and generalise stages
LAZY_IMPORTS = ("mlflow", "mlflow.store.tracking.sqlalchemy_store", "mlflow.entities", "mlflow.models",
                "mlflow.pytorch", "mlflow.onnx", "mlflow.system_metrics.system_metrics_monitor", "psutil", "numba",
                "torch._inductor")
_HEADER = struct.Struct("!I")


@dataclass
class Job:
    """A stage to run in a runner: what ``python -m module *args`` in ``cwd`` under ``env`` would run."""

    module: str
    args: list[str]
    cwd: str
    env: dict[str, str]
    fds: list[int]  # the stage process's stdin, stdout, stderr (a pool worker: and its channel)
    kind: str = "stage"  # or "worker": a process of a stage's pool (toolpath.pipeline.warm_pool)
    sys_path: list[str] | None = None  # a worker's: its stage's
    main: str | None = None  # a worker's: the module its stage runs as __main__ (functions pickled from there)


def _identity() -> dict[str, str]:
    """What a client and the server must share: the interpreter and the toolpath package it imports."""
    import toolpath

    return {"python": os.path.realpath(sys.executable), "toolpath": os.path.realpath(toolpath.__file__)}


# --- the stage's side --------------------------------------------------------------------------------------

def hand_over_stage() -> None:
    """In a process started as ``python -m toolpath.stages.<name> ...`` under a warm server: run the stage
    there and exit with its status.  Returns (the stage runs here) when there is no server to take it."""
    path, argv = os.environ.get(SOCKET_ENV), getattr(sys, "orig_argv", [])
    if not path or len(argv) < 3 or argv[1] != "-m" or not argv[2].startswith(STAGES):
        return
    code = run_in_server(Path(path), argv[2], argv[3:])
    if code is not None:
        sys.exit(code)
    print(f"toolpath: the warm server at {path} did not take {argv[2]} (gone, or started from another interpreter "
          "or checkout): running it in this process", file=sys.stderr)


def run_in_server(path: Path, module: str, args: list[str]) -> int | None:
    """Run ``python -m module *args`` in the warm server at ``path`` with this process's standard streams,
    folder and environment; its exit code (128 + n for a signal n), or None if no server took it."""
    env = {k: v for k, v in os.environ.items() if k != SOCKET_ENV}
    started = start(path, {"module": module, "args": args, "env": {**env, STAGE_PID_ENV: str(os.getpid())}},
                    [0, 1, 2])
    if started is None:
        return None
    conn, runner = started
    with conn:
        forward = {sig: signal.signal(sig, lambda s, _f: _kill(runner, s))
                   for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)}
        try:
            status = conn.makefile("r", encoding="utf-8").readline().split()
        finally:
            for sig, handler in forward.items():
                signal.signal(sig, handler)
    if status[:1] == ["exit"]:
        return int(status[1])
    if status[:1] == ["signal"]:
        return 128 + int(status[1])
    print(f"toolpath: the warm server lost stage {module} (runner {runner})", file=sys.stderr)
    return 1


def start(path: Path, request: dict, fds: list[int]) -> tuple[socket.socket, int] | None:
    """Have the server at ``path`` fork a runner for ``request`` (``module``, ``args``, ``env``; ``kind``
    "worker" for a pool worker) given ``fds`` as its 0, 1, 2 (and 3); the connection on which the runner's
    exit status will come, and the runner's pid; None if no server took it."""
    conn = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    try:
        conn.connect(str(path))
        payload = json.dumps({**_identity(), "cwd": os.getcwd(), **request}).encode()
        socket.send_fds(conn, [_HEADER.pack(len(payload))], fds)
        conn.sendall(payload)
        first = conn.makefile("r", encoding="utf-8").readline().split()
    except OSError:
        first = []
    if first[:1] != ["pid"]:
        conn.close()
        return None  # refused (another interpreter or checkout) or gone
    return conn, int(first[1])


def _kill(pid: int, sig: int) -> None:
    with contextlib.suppress(ProcessLookupError):
        os.kill(pid, sig)


# --- the server's side -------------------------------------------------------------------------------------

def preload() -> None:
    """Import what every stage module imports, and what stages import lazily (:data:`LAZY_IMPORTS`), then
    forget the ``toolpath`` modules (the runners import them from disk); this module and its packages stay."""
    import importlib
    import pkgutil

    # by name, as `python -m` loads a stage: the stages stay leaves that no module imports
    stages = importlib.import_module(STAGES.rstrip("."))
    for found in pkgutil.iter_modules(stages.__path__, STAGES):
        importlib.import_module(found.name)
    for name in LAZY_IMPORTS:
        with contextlib.suppress(ImportError):
            importlib.import_module(name)
    keep = {"toolpath", "toolpath.pipeline", MODULE}
    for name in [n for n in sys.modules if (n == "toolpath" or n.startswith("toolpath.")) and n not in keep]:
        del sys.modules[name]


def serve(path: Path, warm: bool = True) -> Job | None:
    """Listen at ``path`` (bound before :func:`preload`, so stages started meanwhile wait for it) until this
    process's parent is gone or it is terminated.  Returns only in a forked runner, with its job."""
    signal.signal(signal.SIGCHLD, signal.SIG_IGN)  # the kernel reaps finished watchers
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(0))
    parent = os.getppid()
    identity = _identity()
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as listener:
        listener.bind(str(path))
        listener.listen(64)
        if warm:
            preload()
        # what is loaded now stays out of every runner's garbage collections: a full collection would walk the
        # millions of objects of torch & co. (which a spawned process imports in part), and writing their headers
        # would copy the pages the runners share with this process
        gc.collect()
        gc.freeze()
        listener.settimeout(1.0)
        while os.getppid() == parent:
            try:
                conn, _ = listener.accept()
            except TimeoutError:
                continue
            conn.settimeout(None)
            job = _receive(conn, identity)
            if job is None:
                conn.close()
                continue
            if os.fork() == 0:
                listener.close()
                job.env[POOL_ENV] = str(path)  # the stage's pools fork their workers here too
                return _watch(conn, job)  # returns in the runner only
            conn.close()
            for fd in job.fds:
                os.close(fd)
    return None


def _receive(conn: socket.socket, identity: dict[str, str]) -> Job | None:
    """A stage's request, or None (refused: told so) for another interpreter or toolpath checkout."""
    try:
        header, fds, _, _ = socket.recv_fds(conn, _HEADER.size, 4)
        (size,) = _HEADER.unpack(header)
        payload = b""
        while len(payload) < size:
            chunk = conn.recv(size - len(payload))
            if not chunk:
                raise OSError("the stage hung up")
            payload += chunk
        request = json.loads(payload)
    except (OSError, ValueError, struct.error):
        return None
    kind = request.get("kind", "stage")
    if any(request.get(k) != v for k, v in identity.items()) or len(fds) != (3 if kind == "stage" else 4):
        for fd in fds:
            os.close(fd)
        with contextlib.suppress(OSError):
            conn.sendall(b"refused another interpreter or checkout\n")
        return None
    return Job(request.get("module", ""), request.get("args", []), request["cwd"], request["env"], fds, kind,
               request.get("sys_path"), request.get("main"))


def _watch(conn: socket.socket, job: Job) -> Job:
    """In the watcher: fork the runner (which gets ``job`` back), send its pid, wait for it, send its
    exit status; if the stage's process hangs up first, terminate the runner."""
    signal.signal(signal.SIGCHLD, signal.SIG_DFL)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    runner = os.fork()
    if runner == 0:
        conn.close()
        return job
    for fd in job.fds:
        os.close(fd)
    code = 1
    try:
        conn.sendall(f"pid {runner}\n".encode())
        status = _wait(runner, conn)
        code = os.waitstatus_to_exitcode(status)
        conn.sendall((f"exit {code}\n" if code >= 0 else f"signal {-code}\n").encode())
        code = 0
    except OSError:
        _kill(runner, signal.SIGTERM)
    finally:
        os._exit(code)


def _wait(pid: int, conn: socket.socket) -> int:
    """The wait status of child ``pid``; terminates it (and keeps waiting) if ``conn`` hangs up first."""
    with selectors.DefaultSelector() as selector:
        selector.register(conn, selectors.EVENT_READ)
        hung_up = False
        while True:
            done, status = os.waitpid(pid, os.WNOHANG)
            if done:
                return status
            if not hung_up and selector.select(timeout=0.05) and not conn.recv(1, socket.MSG_PEEK):
                hung_up = True
                _kill(pid, signal.SIGTERM)
            elif hung_up:
                time.sleep(0.05)


def become(job: Job) -> None:
    """In a runner: take the stage's streams (fresh stream objects, so buffering and isatty follow them, not
    the server's), folder, environment and import path (``python -m``'s: the folder first)."""
    for target, fd in enumerate(job.fds[:3]):
        os.dup2(fd, target)
        os.close(fd)
    sys.stdin = sys.__stdin__ = open(0, encoding=sys.stdin.encoding, closefd=False)  # noqa: SIM115
    sys.stdout = sys.__stdout__ = open(1, "w", encoding=sys.stdout.encoding, closefd=False,  # noqa: SIM115
                                       buffering=1 if os.isatty(1) else -1)
    sys.stderr = sys.__stderr__ = open(2, "w", encoding=sys.stderr.encoding, errors="backslashreplace",  # noqa: SIM115
                                       closefd=False, buffering=1)
    os.chdir(job.cwd)
    os.environ.clear()
    os.environ.update(job.env)
    if job.sys_path is not None:
        sys.path[:] = job.sys_path
    else:
        sys.path[0] = job.cwd


def run_job(job: Job) -> int:
    """In the runner: become the stage's process and run its module as ``python -m`` would, ending as it
    would (exit code, traceback) but without the interpreter's teardown of every module (:func:`finish`)."""
    import runpy

    become(job)
    sys.argv = [job.module, *job.args]
    try:
        runpy.run_module(job.module, run_name="__main__", alter_sys=True)
        code = 0
    except SystemExit as stop:
        code = _exit_code(stop.code)
    except KeyboardInterrupt:
        code = 128 + signal.SIGINT
    except BaseException:  # noqa: BLE001 -- reported as an uncaught exception is, then the process ends
        sys.excepthook(*sys.exc_info())
        code = 1
    return finish(code)


def finish(code: int) -> int:
    """End a runner as the interpreter would, without its teardown of every module (0.5-1.7 s after a stage
    with torch and MLflow loaded): non-daemon threads joined, ``atexit`` handlers run (MLflow's, logging's
    flush), streams flushed, then ``os._exit``."""
    import atexit
    import threading

    for thread in threading.enumerate():
        if thread is not threading.main_thread() and not thread.daemon:
            thread.join()
    atexit._run_exitfuncs()
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(OSError, ValueError):
            stream.flush()
    os._exit(code)


def _exit_code(code: object) -> int:
    """The exit status ``sys.exit(code)`` gives: None 0, an int itself, anything else printed and 1."""
    if code is None:
        return 0
    if isinstance(code, int):
        return code & 0xFF
    print(code, file=sys.stderr)
    return 1


# --- the wrapper -------------------------------------------------------------------------------------------

def run_with_server(command: list[str]) -> int:
    """Run ``command`` with a warm server for the stages it starts; its exit code."""
    with tempfile.TemporaryDirectory(prefix="toolpath-warm-") as folder:
        path = Path(folder) / "stages.sock"
        server = subprocess.Popen([sys.executable, "-m", MODULE, "--serve", str(path)], start_new_session=True,
                                  stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL)
        deadline = time.monotonic() + 60
        while not path.exists() and server.poll() is None and time.monotonic() < deadline:
            time.sleep(0.02)
        env = {**os.environ, SOCKET_ENV: str(path)} if path.exists() else dict(os.environ)
        interrupt = signal.signal(signal.SIGINT, signal.SIG_IGN)  # the command handles Ctrl-C itself
        try:
            return subprocess.call(command, env=env)
        finally:
            signal.signal(signal.SIGINT, interrupt)
            server.terminate()
            try:
                server.wait(10)
            except subprocess.TimeoutExpired:
                server.kill()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--serve", type=Path, help=argparse.SUPPRESS)  # the server itself, at this socket
    parser.add_argument("--cold", action="store_true", help=argparse.SUPPRESS)  # serve without preloading (tests)
    parser.add_argument("command", nargs=argparse.REMAINDER, help="the command, after --")
    args = parser.parse_args(argv)
    if args.serve:
        job = serve(args.serve, warm=not args.cold)
        if job is not None and job.kind == "worker":
            from toolpath.pipeline.warm_pool import serve_calls

            return serve_calls(job)
        return 0 if job is None else run_job(job)
    command = args.command[1:] if args.command[:1] == ["--"] else args.command
    if not command:
        parser.error("no command given (put it after --)")
    return run_with_server(command)


if __name__ == "__main__":
    sys.exit(main())
