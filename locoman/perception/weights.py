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


def load_transformers(
    weights_dir: str | None,
    key: str,
    runtime: TorchCfg,
    classes: tuple[str, str],
    what: str,
) -> tuple[Any, Any, Any, Any]:
    """A transformers checkpoint and its processor from a local folder, on ``runtime``'s
    device and dtype, in eval mode: (model, processor, torch device, torch dtype).

    Args:
        weights_dir: Folder with ``config.json``, the weights and the processor's
            ``preprocessor_config.json`` (written by ``save_pretrained``).
        key: The config keys' stem (``perception.masks.sam``): ``<key>_weights_dir`` and
            ``<key>_runtime`` are named in the errors.
        runtime: Device and precision.
        classes: The transformers model and processor classes (``SamModel``,
            ``SamProcessor``).
        what: The model, for the errors (``the SAM checkpoint``).

    Raises:
        ModelError: No folder, no package, no CUDA where asked, or a checkpoint that does
            not load.
    """
    path = check_weights_dir(weights_dir, f"{key}_weights_dir", "config.json")
    device, dtype = torch_runtime(runtime, f"{key}_runtime")
    transformers = require_package("transformers")
    model_class, processor_class = (getattr(transformers, name) for name in classes)
    try:
        model = model_class.from_pretrained(str(path), local_files_only=True, dtype=dtype)
        processor = processor_class.from_pretrained(str(path), local_files_only=True)
    except (OSError, ValueError, KeyError) as exc:  # KeyError: a config lacks a key
        raise ModelError(f"cannot load {what} from {path}: {exc}") from None
    return model.to(device).eval(), processor, device, dtype
