"""Loading learned models: optional packages and local weight folders, with clear errors.

Weights are never downloaded: every learned backend reads a folder named in ``conf/``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from locoman.config.perception import TorchCfg
from locoman.errors import ModelError


def require_package(module: str) -> Any:
    """Import an optional package, or raise a :class:`ModelError` saying how to install it."""
    try:
        return __import__(module)
    except ImportError:
        how = (
            "`.venv/bin/pip install -e .[learned]` (the CPU build, pinned)"
            if module == "torch"
            else f"`.venv/bin/pip install {module}`"
        )
        raise ModelError(
            f"the learned backend needs the {module!r} package: {how}; it is not part of "
            "the default install"
        ) from None


def check_weights_dir(weights_dir: str | None, key: str, marker: str) -> Path:
    """The weights folder, or a :class:`ModelError` saying which config key to set.

    Args:
        weights_dir: Configured folder (None when unset).
        key: Full config key, for the message.
        marker: A file the folder must hold (``model_index.json``, ``config.json``).
    """
    if not weights_dir:
        raise ModelError(
            f"{key} is not set: point it to a local folder holding the model "
            f"(with {marker}); nothing is downloaded"
        )
    path = Path(weights_dir)
    if not (path / marker).is_file():
        raise ModelError(
            f"{key} = {str(path)!r} holds no {marker}: the weights are absent or incomplete "
            "(save the model there with save_pretrained)"
        )
    return path


def torch_runtime(cfg: TorchCfg, key: str) -> tuple[Any, Any]:
    """(torch device, torch dtype) of ``cfg``, or a :class:`ModelError` naming ``key`` when
    it asks for CUDA and torch sees none (the pinned torch is the CPU build)."""
    torch = require_package("torch")
    if cfg.device.startswith("cuda") and not torch.cuda.is_available():
        raise ModelError(
            f"{key}.device = {cfg.device!r}, and torch {torch.__version__} sees no CUDA "
            f"device: set {key}.device=cpu, or install a CUDA build of torch on a GPU machine"
        )
    return torch.device(cfg.device), getattr(torch, cfg.dtype)
