"""The ``flux`` image backend: a diffusers text-to-image pipeline from a local folder.

Paper A generates R_g with a latent diffusion model. Weights are never downloaded here: the
pipeline loads from ``perception.generate.flux.weights_dir`` (a folder written by
``DiffusionPipeline.save_pretrained``, e.g. a local copy of FLUX.1-schnell) and fails with a
clear message when it is absent. Images from this backend carry no ground truth, so the
stages that score against it report that they cannot.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from locoman.config.perception import FluxCfg, GenerateCfg
from locoman.errors import ModelError
from locoman.perception.weights import check_weights_dir, require_package, torch_runtime

KEY = "perception.generate.flux"


def load_flux_pipeline(cfg: FluxCfg) -> Any:
    """The diffusers pipeline stored in ``cfg.weights_dir`` (its class comes from the
    folder's ``model_index.json``: FluxPipeline for FLUX.1), on ``cfg.runtime``'s device in
    its dtype."""
    path = check_weights_dir(cfg.weights_dir, f"{KEY}.weights_dir", "model_index.json")
    device, dtype = torch_runtime(cfg.runtime, f"{KEY}.runtime")
    diffusers = require_package("diffusers")
    try:
        pipe = diffusers.DiffusionPipeline.from_pretrained(
            str(path), local_files_only=True, dtype=dtype
        )
    except (OSError, ValueError, KeyError) as exc:  # KeyError: a config lacks a key
        raise ModelError(f"cannot load the diffusion pipeline from {path}: {exc}") from None
    return pipe.to(device)


def generate_image(pipe: Any, prompt: str, cfg: GenerateCfg, seed: int) -> np.ndarray:
    """One image (H, W, 3) uint8 for ``prompt``, reproducible for a given ``seed``."""
    torch = require_package("torch")
    generator = torch.Generator(device="cpu").manual_seed(seed)
    out = pipe(
        prompt=prompt,
        height=cfg.height,
        width=cfg.width,
        num_inference_steps=cfg.flux.steps,
        guidance_scale=cfg.flux.guidance_scale,
        max_sequence_length=cfg.flux.max_sequence_length,
        generator=generator,
        output_type="np",
    )
    image = np.asarray(out.images[0], dtype=np.float32)
    return (np.clip(image, 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)
