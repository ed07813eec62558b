"""The CPU kernels every process runs: toolpath pins numpy (and its OpenBLAS), torch, oneDNN and MKL to
their AVX2 kernels before either is imported, so a seed gives the same bytes on an AVX2 and an AVX-512 host."""

import os
import platform
import subprocess
import sys

import pytest

import toolpath

pytestmark = pytest.mark.skipif(platform.machine().lower() not in ("x86_64", "amd64"),
                                reason="the pins are for x86-64 kernels")

PROBE = ("import os, toolpath, numpy, torch; from numpy._core._multiarray_umath import __cpu_features__ as f; "
         "from threadpoolctl import threadpool_info as pools; "
         "blas = [p['architecture'] for p in pools() if p['internal_api'] == 'openblas' and 'numpy' in p['filepath']]; "
         "print(f['X86_V4'], torch.backends.cpu.get_cpu_capability(), ','.join(blas) or '-', "
         "'|'.join(os.environ.get(k, '-').replace(' ', '+') for k in sorted(toolpath.CPU_PINS)))")


def _probe(env: dict) -> list[str]:
    done = subprocess.run([sys.executable, "-c", PROBE], env=env, capture_output=True, text=True, check=True)
    return done.stdout.split()


def _without_pins() -> dict:
    return {k: v for k, v in os.environ.items() if k not in toolpath.CPU_PINS}


def test_importing_toolpath_first_runs_numpy_and_torch_on_avx2_kernels():
    v4, torch_kernels, numpy_blas, pins = _probe(_without_pins())
    # every pin is set in the process (on any x86-64 host), before numpy and torch read them
    assert pins == "|".join(toolpath.CPU_PINS[k].replace(" ", "+") for k in sorted(toolpath.CPU_PINS))
    assert v4 == "False"  # numpy's AVX-512 dispatch off (on an AVX2 host it never was on)
    assert torch_kernels in ("AVX2", "DEFAULT")
    assert numpy_blas == "Haswell"  # numpy's OpenBLAS (SkylakeX on an AVX-512 host without the pin)


def test_a_pin_the_environment_sets_itself_is_kept():
    env = _without_pins() | {"ATEN_CPU_CAPABILITY": "default"}
    assert _probe(env)[1] == "DEFAULT"
