"""The warm server of `make repro` (toolpath.pipeline.warm): a stage handed to it runs as `python -m` would run
it in the stage's own process (streams, folder, arguments, environment, exit status, signals); with no server the
stage runs where it was started.  That a stage writes the same bytes either way is checked end to end
(tests/test_pipeline.py: every stage of the smoke repro runs warm, one runs again cold, and DVC finds nothing
changed)."""

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from toolpath.pipeline import warm

PROBE = """
import json, os, sys
line = sys.stdin.readline().strip()
print(json.dumps({"argv": sys.argv[1:], "cwd": os.getcwd(), "x": os.environ.get("PROBE_X"), "stdin": line,
                  "stage_pid": os.environ.get("TOOLPATH_STAGE_PID"), "socket": os.environ.get("TOOLPATH_WARM_SOCKET"),
                  "ours_loaded": "toolpath.stages" in sys.modules, "path0": sys.path[0]}))
print("to stderr", file=sys.stderr)
if "boom" in sys.argv:
    raise RuntimeError("boom from the probe")
if "sleep" in sys.argv:
    open("pid", "w").write(str(os.getpid()))
    import time
    time.sleep(60)
sys.exit(3)
"""

CLIENT = ("import sys; from pathlib import Path; from toolpath.pipeline.warm import run_in_server; "
          "code = run_in_server(Path(sys.argv[1]), 'probe', sys.argv[2:]); "
          "sys.exit(99 if code is None else code)")


@pytest.fixture
def server(warm_server):
    return warm_server


def probe_folder(tmp_path: Path) -> Path:
    folder = tmp_path / "stage"
    folder.mkdir()
    (folder / "probe.py").write_text(PROBE)
    return folder


def test_a_handed_over_module_runs_with_the_stages_streams_folder_arguments_environment_and_exit_code(
        server, tmp_path):
    folder = probe_folder(tmp_path)
    client = subprocess.Popen([sys.executable, "-c", CLIENT, str(server), "a", "b c"], cwd=folder,
                              env={**os.environ, "PROBE_X": "1", warm.SOCKET_ENV: str(server)},
                              stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    out, err = client.communicate("hello\n", timeout=60)
    assert client.returncode == 3, err
    seen = json.loads(out)
    assert seen == {"argv": ["a", "b c"], "cwd": str(folder), "x": "1", "stdin": "hello",
                    "stage_pid": str(client.pid), "socket": None, "ours_loaded": False, "path0": str(folder)}
    assert "to stderr" in err


def test_an_uncaught_exception_prints_its_traceback_and_exits_1(server, tmp_path):
    done = subprocess.run([sys.executable, "-c", CLIENT, str(server), "boom"], cwd=probe_folder(tmp_path),
                          input="\n", capture_output=True, text=True, timeout=60)
    assert done.returncode == 1
    assert "Traceback" in done.stderr and "RuntimeError: boom from the probe" in done.stderr


def test_terminating_the_stages_process_terminates_its_runner(server, tmp_path):
    folder = probe_folder(tmp_path)
    client = subprocess.Popen([sys.executable, "-c", CLIENT, str(server), "sleep"], cwd=folder,
                              stdin=subprocess.PIPE, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    client.stdin.write(b"\n")
    client.stdin.close()
    deadline = time.monotonic() + 30
    while not (folder / "pid").is_file() or not (folder / "pid").read_text():
        assert time.monotonic() < deadline, "the runner did not start"
        time.sleep(0.05)
    runner = int((folder / "pid").read_text())
    client.send_signal(signal.SIGTERM)
    assert client.wait(30) == 128 + signal.SIGTERM  # forwarded: the runner's death is the stage's status
    deadline = time.monotonic() + 10
    while Path(f"/proc/{runner}").exists() and "Z" not in Path(f"/proc/{runner}/stat").read_text().split()[2]:
        assert time.monotonic() < deadline, "the runner outlived its stage"
        time.sleep(0.05)


def test_without_a_server_or_for_another_interpreter_the_stage_runs_where_it_started(server, tmp_path, monkeypatch):
    assert warm.run_in_server(tmp_path / "none.sock", "probe", []) is None
    monkeypatch.setattr(warm, "_identity", lambda: {"python": "/elsewhere/python", "toolpath": "/elsewhere"})
    assert warm.run_in_server(server, "probe", []) is None  # refused before any runner starts


def _square_with_offset(x):
    return x * x + OFFSET[0]


OFFSET = [0]


def _set_offset(value):
    OFFSET[0] = value


def _fail(x):
    raise ValueError(f"no {x}")


def _die(_x):
    os._exit(7)


def test_a_warm_pool_runs_calls_in_forked_workers_with_the_initializer_and_their_exceptions(server, monkeypatch):
    from toolpath.pipeline.warm_pool import WarmPool

    with WarmPool(server, 2, initializer=_set_offset, initargs=(100,)) as pool:
        assert list(pool.map(_square_with_offset, range(6))) == [100 + x * x for x in range(6)]
        assert os.getpid() not in {f.result() for f in [pool.submit(os.getpid) for _ in range(4)]}
        failed = pool.submit(_fail, 3)
        with pytest.raises(ValueError, match="no 3") as raised:
            failed.result()
        assert "no 3" in str(raised.value.__cause__)  # the worker's traceback
        assert pool.submit(_square_with_offset, 2).result() == 104  # the pool lives on after a call's exception


def test_a_dying_warm_worker_breaks_its_pool(server):
    from concurrent.futures.process import BrokenProcessPool

    from toolpath.pipeline.warm_pool import WarmPool

    with WarmPool(server, 1) as pool:
        with pytest.raises(BrokenProcessPool):
            pool.submit(_die, 0).result(timeout=30)
        with pytest.raises(BrokenProcessPool):
            pool.submit(_square_with_offset, 1).result(timeout=30)


def test_a_process_pool_is_warm_only_under_a_server(server, monkeypatch):
    from concurrent.futures import ProcessPoolExecutor

    from toolpath.pipeline.warm_pool import WarmPool, process_pool

    monkeypatch.delenv(warm.POOL_ENV, raising=False)
    with process_pool(1) as pool:
        assert isinstance(pool, ProcessPoolExecutor)
    monkeypatch.setenv(warm.POOL_ENV, str(server))
    with process_pool(1) as pool:
        assert isinstance(pool, WarmPool) and pool.submit(_square_with_offset, 3).result() == 9
    monkeypatch.setenv(warm.POOL_ENV, str(server.parent / "gone.sock"))
    with process_pool(1) as pool:
        assert isinstance(pool, ProcessPoolExecutor)


def test_a_warm_pool_runs_functions_of_the_module_its_stage_runs_as_main(server, tmp_path):
    """A stage module's own function, pickled as ``__main__.<name>``, runs in a warm worker (as in a spawned one)."""
    folder = tmp_path / "stage"
    folder.mkdir()
    (folder / "poolstage.py").write_text(
        "import sys\n"
        "from pathlib import Path\n"
        "from toolpath.pipeline.warm_pool import WarmPool\n"
        "def double(x):\n    return 2 * x\n"
        "if __name__ == '__main__':\n"
        "    with WarmPool(Path(sys.argv[1]), 2) as pool:\n"
        "        print(list(pool.map(double, [1, 2, 3])))\n")
    client = ("import sys; from pathlib import Path; from toolpath.pipeline.warm import run_in_server; "
              "sys.exit(run_in_server(Path(sys.argv[1]), 'poolstage', sys.argv[1:]))")
    done = subprocess.run([sys.executable, "-c", client, str(server)], cwd=folder, capture_output=True, text=True,
                          timeout=60)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.strip() == "[2, 4, 6]"


def test_a_warm_pool_runs_functions_of_a_script_run_as_main(server, tmp_path):
    script = tmp_path / "poolscript.py"
    script.write_text(
        "import sys\n"
        "from pathlib import Path\n"
        "from toolpath.pipeline.warm_pool import WarmPool\n"
        "def triple(x):\n    return 3 * x\n"
        "if __name__ == '__main__':\n"
        "    with WarmPool(Path(sys.argv[1]), 1) as pool:\n"
        "        print(list(pool.map(triple, [1, 2])))\n")
    done = subprocess.run([sys.executable, str(script), str(server)], capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.strip() == "[3, 6]"


def test_a_stage_the_named_server_does_not_take_says_so_and_runs_where_it_started(tmp_path):
    folder = probe_folder(tmp_path)
    done = subprocess.run([sys.executable, "-c", "from toolpath.pipeline.warm import hand_over_stage; "
                           "import sys; sys.orig_argv[1:] = ['-m', 'toolpath.stages.nothing']; hand_over_stage(); "
                           "print('ran here')"], cwd=folder, capture_output=True, text=True, timeout=60,
                          env={**os.environ, warm.SOCKET_ENV: str(tmp_path / "gone")})
    assert done.returncode == 0 and done.stdout.strip() == "ran here"
    assert f"the warm server at {tmp_path / 'gone'} did not take toolpath.stages.nothing" in done.stderr
