"""toolpath-lab: CNC toolpath roughness recognition and smoothing.

Domain sub-packages (``gcode``, ``geometry``, ``shapes``, ``labels`` ...) take and return arrays and
dataclasses; only ``toolpath.stages`` reads files named in ``params.yaml`` and talks to MLflow.
"""

import os as _os
import platform as _platform

__version__ = "0.1.0"

# The same bytes on every x86-64 machine: numpy, torch (ATen, oneDNN, MKL) pick their kernels by the CPU's
# instruction set, and their AVX-512 kernels round some results differently from the AVX2 ones (a seeded
# gear program set came out 31 bytes longer on an AVX-512 host than on an AVX2 host, and with it the
# labels and the split changed).  numpy's OpenBLAS picks its own kernels (SkylakeX on an AVX-512 host:
# the logistic-regression reference of Table 3 moved in its 4th digit).  Every process that imports
# toolpath before numpy or torch runs the AVX2 kernels, unless its environment sets these variables
# itself.  MKL honours MKL_CBWR on Intel CPUs only (on AMD it reports CNR:AUTO, one generic path).
CPU_PINS = {"NPY_DISABLE_CPU_FEATURES": "X86_V4 AVX512_ICL AVX512_SPR", "ATEN_CPU_CAPABILITY": "avx2",
            "ONEDNN_MAX_CPU_ISA": "AVX2", "MKL_CBWR": "AVX2", "OPENBLAS_CORETYPE": "Haswell"}
if _platform.machine().lower() in ("x86_64", "amd64"):
    for _name, _value in CPU_PINS.items():
        _os.environ.setdefault(_name, _value)
