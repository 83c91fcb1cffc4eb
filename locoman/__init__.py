"""locoman: human demonstrations to physically consistent robot loco-manipulation.

Sub-packages are split by what the code is about: ``scene`` (robots, objects, scenarios),
``artifacts`` (typed, atomic files), ``config`` (typed configuration), and one package per
pipeline stage family as they land.
"""

__version__ = "0.1.0"
