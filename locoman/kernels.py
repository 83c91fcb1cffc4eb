"""The numerical libraries' CPU kernels, pinned to one instruction-set level.

OpenBLAS (NumPy's and SciPy's; CasADi's is built for one core type), NumPy and OpenCV pick
their kernels when they load, by what the CPU offers: AVX-512 kernels where it has them,
AVX2 ones where not. Those round differently in the last bits, and the differences grow
through the pipeline (a scene's initial state, then every stage after it): a machine with
AVX-512 wrote other artifacts than one without, from the same parameters.
:func:`pin_kernels` sets, before those libraries load, the variables that keep them at their
AVX2 kernels on every x86-64 CPU with AVX2. Importing ``locoman`` sets nothing: each entry
point that writes artifacts calls it first (every stage, before its other imports;
``tests/test_kernels.py`` checks), and the grid launcher passes the pins to its jobs. A
variable the user set is left as it is.
"""

from __future__ import annotations

import os
import platform
from collections.abc import MutableMapping
from pathlib import Path

# NumPy's and OpenCV's names of the AVX-512 extensions their dispatchers know.
_NUMPY_AVX512 = (
    "AVX512F", "AVX512CD", "AVX512_KNL", "AVX512_KNM", "AVX512_SKX", "AVX512_CLX", "AVX512_CNL",
    "AVX512_ICL", "AVX512_SPR",
)  # fmt: skip
# OpenCV's names of its AVX-512 dispatch groups (``cv::getCPUFeaturesLine()``, hyphenated),
# each with the Linux CPU flags it needs: OpenCV warns about a name it does not know or a
# group this CPU lacks, so only the groups the CPU has are disabled.
_OPENCV_AVX512 = {
    "AVX512-COMMON": ("avx512f", "avx512cd"),
    "AVX512-SKX": ("avx512f", "avx512cd", "avx512bw", "avx512dq", "avx512vl"),
    "AVX512-KNL": ("avx512f", "avx512cd", "avx512er", "avx512pf"),
    "AVX512-KNM": ("avx512f", "avx512cd", "avx512er", "avx512pf", "avx512_4fmaps",
                   "avx512_4vnniw", "avx512_vpopcntdq"),
    "AVX512-CNL": ("avx512f", "avx512cd", "avx512bw", "avx512dq", "avx512vl", "avx512ifma",
                   "avx512vbmi"),
    "AVX512-CLX": ("avx512f", "avx512cd", "avx512bw", "avx512dq", "avx512vl", "avx512_vnni"),
    "AVX512-ICL": ("avx512f", "avx512cd", "avx512bw", "avx512dq", "avx512vl", "avx512ifma",
                   "avx512vbmi", "avx512_vnni", "avx512_vbmi2", "avx512_bitalg",
                   "avx512_vpopcntdq"),
}  # fmt: skip


def cpu_flags(cpuinfo: Path = Path("/proc/cpuinfo")) -> set[str]:
    """The CPU's feature flags (Linux's ``/proc/cpuinfo``; empty where it cannot tell)."""
    try:
        lines = cpuinfo.read_text().splitlines()
    except OSError:
        return set()
    return next((set(ln.split(":", 1)[1].split()) for ln in lines if ln.startswith("flags")), set())


def kernel_pins(machine: str, flags: set[str]) -> dict[str, str]:
    """The variables that keep the libraries at AVX2 kernels on this CPU; none where it has
    no AVX2 (a forced Haswell kernel would be an illegal instruction) or is not x86-64."""
    if machine.lower() not in ("x86_64", "amd64") or not {"avx2", "fma"} <= flags:
        return {}
    pins = {
        # OpenBLAS's DYNAMIC_ARCH family; SkylakeX and Cooperlake are its AVX-512 ones.
        "OPENBLAS_CORETYPE": "Haswell",
        # NumPy's dispatched loops (sums; exp, log, trig through SVML) above AVX2.
        "NPY_DISABLE_CPU_FEATURES": ",".join(_NUMPY_AVX512),
    }
    opencv = [name for name, needs in _OPENCV_AVX512.items() if set(needs) <= flags]
    if opencv:
        pins["OPENCV_CPU_DISABLE"] = ",".join(opencv)
    return pins


def pin_kernels(environ: MutableMapping[str, str] = os.environ) -> dict[str, str]:
    """Set :func:`kernel_pins` of this machine in ``environ`` where unset; return them."""
    added = {
        k: v for k, v in kernel_pins(platform.machine(), cpu_flags()).items() if k not in environ
    }
    environ.update(added)
    return added
