"""locoman: human demonstrations to physically consistent robot loco-manipulation.

Sub-packages are split by what the code is about: ``scene`` (robots, objects, scenarios),
``artifacts`` (typed, atomic files), ``config`` (typed configuration), and one package per
pipeline stage family as they land.

Importing it changes no process-wide setting. An entry point that writes artifacts (every
stage in ``stages/``, the grid's Hydra app) calls :func:`locoman.kernels.pin_kernels` before
it loads NumPy, so that the same parameters give the same bits on every x86-64 CPU.
"""

__version__ = "0.1.0"
