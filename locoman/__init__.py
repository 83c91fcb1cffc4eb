"""locoman: human demonstrations to physically consistent robot loco-manipulation.

Sub-packages are split by what the code is about: ``scene`` (robots, objects, scenarios),
``artifacts`` (typed, atomic files), ``config`` (typed configuration), and one package per
pipeline stage family as they land.
"""

from locoman.kernels import pin_kernels

# Before NumPy, OpenBLAS or OpenCV load: the same kernels, so the same artifacts, on every
# x86-64 CPU with AVX2.
pin_kernels()

__version__ = "0.1.0"
