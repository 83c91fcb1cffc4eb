"""The ``flux`` image backend: a diffusers text-to-image pipeline from a local folder.

Paper A generates R_g with a latent diffusion model. Weights are never downloaded here: the
pipeline loads from ``perception.generate.flux.weights_dir`` (a folder written by
``DiffusionPipeline.save_pretrained``, e.g. a local copy of FLUX.1-schnell) and fails with a
clear message when it is absent. Images from this backend carry no ground truth, so the
stages that score against it report that they cannot.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from locoman.config.perception import FluxCfg, GenerateCfg
from locoman.errors import ModelError


def _require(module: str) -> Any:
    try:
        return __import__(module)
    except ImportError:
        raise ModelError(
            f"the learned backend needs the {module!r} package: "
            f"`.venv/bin/pip install {module}` (it is not part of the default install)"
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


def load_flux_pipeline(cfg: FluxCfg) -> Any:
    """The diffusers pipeline stored in ``cfg.weights_dir`` (its class comes from the
    folder's ``model_index.json``: FluxPipeline for FLUX.1), on ``cfg.device``."""
    path = check_weights_dir(
        cfg.weights_dir, "perception.generate.flux.weights_dir", "model_index.json"
    )
    diffusers = _require("diffusers")
    try:
        pipe = diffusers.DiffusionPipeline.from_pretrained(str(path), local_files_only=True)
    except (OSError, ValueError) as exc:
        raise ModelError(f"cannot load the diffusion pipeline from {path}: {exc}") from None
    return pipe.to(cfg.device)


def generate_image(pipe: Any, prompt: str, cfg: GenerateCfg, seed: int) -> np.ndarray:
    """One image (H, W, 3) uint8 for ``prompt``, reproducible for a given ``seed``."""
    torch = _require("torch")
    generator = torch.Generator(device="cpu").manual_seed(seed)
    out = pipe(
        prompt=prompt,
        height=cfg.height,
        width=cfg.width,
        num_inference_steps=cfg.flux.steps,
        guidance_scale=cfg.flux.guidance_scale,
        generator=generator,
        output_type="np",
    )
    image = np.asarray(out.images[0])
    return (np.clip(image, 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)
