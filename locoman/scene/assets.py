"""Robot description files shipped by the ``example-robot-data`` package.

Nothing is downloaded: the URDFs and meshes live in the installed wheel under
``cmeel.prefix/share/example-robot-data/robots``. URDF mesh paths use
``package://example-robot-data/robots/...``; :func:`urdf_text` rewrites them to a directory of
the caller's choice so MuJoCo and Pinocchio can both read the same text.
"""

from __future__ import annotations

import functools
import importlib.metadata
from pathlib import Path

from locoman.errors import ModelError

PACKAGE_PREFIX = "package://example-robot-data/robots/"

G1_URDF = "g1_description/urdf/g1_29dof_rev_1_0.urdf"
HUMAN_URDF = "human_description/robots/human.urdf"
PANDA_URDF = "panda_description/urdf/panda.urdf"


@functools.cache
def robots_dir() -> Path:
    """Directory holding the ``*_description`` folders of ``example-robot-data``."""
    try:
        dist = importlib.metadata.distribution("example-robot-data")
    except importlib.metadata.PackageNotFoundError as exc:
        raise ModelError(
            "example-robot-data is not installed; run `make setup` (or "
            "`pip install example-robot-data==6.0.0`)"
        ) from exc
    for file in dist.files or []:
        if str(file).endswith(G1_URDF):
            path = Path(str(dist.locate_file(file)))
            return path.parents[2]
    raise ModelError(
        f"example-robot-data is installed but has no {G1_URDF}; reinstall example-robot-data==6.0.0"
    )


def urdf_path(relative: str) -> Path:
    """Absolute path of a URDF given relative to :func:`robots_dir`."""
    path = robots_dir() / relative
    if not path.is_file():
        raise ModelError(f"robot description {path} is missing; reinstall example-robot-data")
    return path


def urdf_text(relative: str, mesh_root: str | Path | None = None) -> str:
    """URDF text with ``package://`` mesh paths resolved.

    Args:
        relative: URDF path relative to :func:`robots_dir`.
        mesh_root: Directory that replaces ``package://example-robot-data/robots/``. Default:
            the absolute :func:`robots_dir`. An empty string leaves paths relative to the robots
            directory, which is what an MJCF with ``meshdir`` set to that directory needs.
    """
    root = str(robots_dir()) if mesh_root is None else str(mesh_root)
    prefix = "" if root == "" else root.rstrip("/") + "/"
    return urdf_path(relative).read_text().replace(PACKAGE_PREFIX, prefix)
