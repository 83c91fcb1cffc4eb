"""What every section of the transcription reads (:class:`Section`)."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence

import numpy as np

from locoman.to.problem.modes import NodeMode
from locoman.to.problem.numbers import Numbers
from locoman.to.terms.library import RobotTerms
from locoman.to.transcription.builder import BlockBuilder
from locoman.to.transcription.index import NodeIndex


@dataclasses.dataclass(frozen=True)
class Section:
    """The problem as one section of the transcription sees it.

    Attributes:
        builder: Collects the section's calls (:class:`BlockBuilder`).
        at: Where each variable of a node sits (:class:`NodeIndex`).
        modes: The contact mode of every node (N,).
        numbers: The problem's numbers: weights, contacts, collisions, objects, obstacles.
        robot: The robot's term kinds.
        P: (n_params, N) the per-node numbers
            (:func:`locoman.to.problem.numbers.node_parameters`).
        par: Name -> rows of ``P`` (:attr:`locoman.to.problem.layout.NodeLayout.parameters`).
        opar: (object j, quantity) -> rows of ``P`` of object j
            (:meth:`locoman.to.problem.layout.NodeLayout.object_parameters`).
    """

    builder: BlockBuilder
    at: NodeIndex
    modes: Sequence[NodeMode]
    numbers: Numbers
    robot: RobotTerms
    P: np.ndarray
    par: dict[str, slice]
    opar: Callable[[int, str], slice]
