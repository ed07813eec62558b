"""Process pools whose workers come from ``make repro``'s warm server when the stage runs there, else spawned.

:func:`process_pool` returns a :class:`concurrent.futures.Executor` the stages and the training, QAT and
smoothing runs use as they used ``ProcessPoolExecutor(mp_context=spawn)``: in a stage forked by the warm
server (:mod:`toolpath.pipeline.warm`, which names itself in :data:`~toolpath.pipeline.warm.POOL_ENV`), a
:class:`WarmPool` whose workers the server forks with the pipeline's libraries already imported (a spawned
worker spends about 6 s importing them); elsewhere, or when the server is gone, a spawned
``ProcessPoolExecutor``.  Either way each worker is a fresh process that shares no state with the stage's
(the server never runs torch, so no OpenMP pool is forked), the initializer runs once per worker, calls and
results are pickled, and results do not depend on which worker ran what.

A :class:`WarmPool` worker takes the stage's environment, folder and import path, writes to its stdout and
stderr, and serves pickled calls on a socket pair until the pool shuts down; one thread of the stage per
worker feeds it.  A worker that dies breaks the pool (``BrokenProcessPool``), as a spawned pool does.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import os
import pickle
import queue
import socket
import struct
import sys
import threading
import traceback
from collections.abc import Callable
from concurrent.futures import Executor, Future, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path
from typing import Any

from toolpath.pipeline import warm

_LENGTH = struct.Struct("!Q")


def process_pool(workers: int, initializer: Callable[..., Any] | None = None, initargs: tuple = ()) -> Executor:
    """``workers`` processes: forked by the warm server this stage runs under, else spawned."""
    path = os.environ.get(warm.POOL_ENV)
    if path:
        try:
            return WarmPool(Path(path), workers, initializer, initargs)
        except OSError as exc:
            print(f"toolpath: no warm workers from {path} ({exc}): spawning them", file=sys.stderr)
    return ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("spawn"), initializer=initializer,
                               initargs=initargs)


class RemoteTraceback(Exception):
    """A worker's traceback, as the ``__cause__`` of the exception it raised (as ``ProcessPoolExecutor`` does)."""

    def __str__(self) -> str:
        return f'\n"""\n{self.args[0]}"""'


class WarmPool(Executor):
    """An executor over ``workers`` processes forked by the warm server at ``path``."""

    def __init__(self, path: Path, workers: int, initializer: Callable[..., Any] | None = None,
                 initargs: tuple = ()) -> None:
        self._calls: queue.SimpleQueue = queue.SimpleQueue()
        self._broken: str | None = None
        self._shut = False
        self._workers: list[tuple[socket.socket, socket.socket, threading.Thread]] = []
        try:
            for _ in range(max(1, workers)):
                self._workers.append(self._start_worker(path, (initializer, initargs)))
        except OSError:
            self.shutdown(wait=True)
            raise

    def _start_worker(self, path: Path, init: tuple) -> tuple[socket.socket, socket.socket, threading.Thread]:
        ours, theirs = socket.socketpair()
        with open(os.devnull, "rb") as nothing:
            main = _main_module()
            started = warm.start(path, {"kind": "worker", "env": dict(os.environ), "sys_path": list(sys.path),
                                        "main": main}, [nothing.fileno(), 1, 2, theirs.fileno()])
        theirs.close()
        if started is None:
            ours.close()
            raise OSError("the warm server did not start a worker")
        control, _ = started
        feeder = threading.Thread(target=self._feed, args=(ours, init), daemon=True)
        feeder.start()
        return ours, control, feeder

    def submit(self, fn: Callable[..., Any], /, *args: Any, **kwargs: Any) -> Future:
        if self._shut:
            raise RuntimeError("cannot schedule new futures after shutdown")
        future: Future = Future()
        if self._broken:
            future.set_exception(BrokenProcessPool(self._broken))
            return future
        self._calls.put((future, fn, args, kwargs))
        return future

    def _feed(self, channel: socket.socket, init: tuple) -> None:
        """One worker's thread: initialise it, then send it calls and settle their futures until shutdown."""
        try:
            _send(channel, init)
            status, *failure = _receive(channel)
            if status != "ok":
                self._break(f"a worker's initializer failed:\n{failure[-1]}")
        except (OSError, EOFError, pickle.PickleError) as exc:
            self._break(f"a warm worker did not start: {exc}")
        while (item := self._calls.get()) is not None:
            future, fn, args, kwargs = item
            if not future.set_running_or_notify_cancel():
                continue
            if self._broken:
                future.set_exception(BrokenProcessPool(self._broken))
                continue
            try:
                _send(channel, (fn, args, kwargs))
                status, value, *remote = _receive(channel)
            except (OSError, EOFError) as exc:
                self._break(f"a warm worker died while running {getattr(fn, '__name__', fn)}: {exc!r}")
                future.set_exception(BrokenProcessPool(self._broken))
                continue
            except Exception as exc:  # noqa: BLE001 -- a call or result that does not pickle fails its future
                future.set_exception(exc)
                continue
            if status == "ok":
                future.set_result(value)
            else:
                value.__cause__ = RemoteTraceback(remote[0])
                future.set_exception(value)

    def _break(self, why: str) -> None:
        self._broken = self._broken or why

    def shutdown(self, wait: bool = True, *, cancel_futures: bool = False) -> None:
        if self._shut:
            return
        self._shut = True
        if cancel_futures:
            pending = []
            while True:
                try:
                    pending.append(self._calls.get_nowait())
                except queue.Empty:
                    break
            for future, *_ in filter(None, pending):
                future.cancel()
        for _ in self._workers:
            self._calls.put(None)
        if wait:
            for _, _, feeder in self._workers:
                feeder.join()
        for channel, _, _ in self._workers:
            channel.close()  # the worker sees the end of its calls and exits
        for _, control, _ in self._workers:
            if wait:  # its exit status (else its watcher, seeing the pool gone, terminates it)
                control.settimeout(30)
                with contextlib.suppress(OSError):
                    control.recv(64)
            control.close()


def _send(channel: socket.socket, value: Any) -> None:
    data = pickle.dumps(value, protocol=pickle.HIGHEST_PROTOCOL)
    channel.sendall(_LENGTH.pack(len(data)) + data)


def _receive(channel: socket.socket) -> Any:
    size = _LENGTH.unpack(_exactly(channel, _LENGTH.size))[0]
    return pickle.loads(_exactly(channel, size))


def _exactly(channel: socket.socket, size: int) -> bytes:
    chunks, left = [], size
    while left:
        chunk = channel.recv(min(left, 1 << 20))
        if not chunk:
            raise EOFError("the other end hung up")
        chunks.append(chunk)
        left -= len(chunk)
    return b"".join(chunks)


def _main_module() -> str | None:
    """This process's main module: its name (``python -m``), else the path of its script, else None."""
    main = sys.modules.get("__main__")
    name = getattr(getattr(main, "__spec__", None), "name", None)
    path = getattr(main, "__file__", None)
    return name or (f"path:{os.path.abspath(path)}" if path else None)


def _main_as(main: str) -> None:
    """Load the stage's main module as ``__main__`` without running its main block, so functions pickled from
    it resolve (as a spawned worker does: multiprocessing loads it as ``__mp_main__``)."""
    import runpy
    import types

    module = types.ModuleType("__mp_main__")
    found = runpy.run_path(main[5:], run_name="__mp_main__") if main.startswith("path:") else \
        runpy.run_module(main, run_name="__mp_main__", alter_sys=True)
    module.__dict__.update(found)
    sys.modules["__main__"] = sys.modules["__mp_main__"] = module


def serve_calls(job: warm.Job) -> int:
    """In a worker forked by the warm server: become the stage's process (:func:`~toolpath.pipeline.warm.become`),
    run the initializer, then answer calls with ``("ok", result)`` or ``("error", exception, traceback)``
    until the pool hangs up."""
    channel = socket.socket(fileno=job.fds[3])
    warm.become(job)
    if job.main:
        _main_as(job.main)
    try:
        initializer, initargs = _receive(channel)
        try:
            if initializer is not None:
                initializer(*initargs)
            _send(channel, ("ok",))
        except BaseException:  # noqa: BLE001 -- reported to the pool, which breaks
            _send(channel, ("error", traceback.format_exc()))
            return warm.finish(1)
        while True:
            try:
                fn, args, kwargs = _receive(channel)
            except EOFError:
                break
            try:
                reply = ("ok", fn(*args, **kwargs))
            except BaseException as exc:  # noqa: BLE001 -- the call's exception is its future's
                reply = ("error", exc, traceback.format_exc())
            try:
                _send(channel, reply)
            except Exception as exc:  # noqa: BLE001 -- a result or exception that does not pickle
                _send(channel, ("error", RuntimeError(f"the result did not pickle: {exc!r}"), traceback.format_exc()))
    except (OSError, EOFError):
        return warm.finish(1)
    return warm.finish(0)
