"""The render quality of the videos and filmstrips (``MUJOCO_GL=egl`` renders on the CPU)."""

from __future__ import annotations

import mujoco

# With MuJoCo's defaults (a 4096 px shadow map, 4x multisampling) a 640 x 480 frame of a G1
# scene takes 0.16 s on the idle 2-core machine (Mesa's software rasteriser; 0.23-0.40 s beside
# other work), with these 0.08 s; the shadows stay and the pictures differ only in the edges'
# anti-aliasing (benchmarks/render_quality.py). The scene's overview keeps the defaults.
SHADOW_SIZE = 1024  # [px]
MULTISAMPLES = 0


def media_quality(model: mujoco.MjModel) -> mujoco.MjModel:
    """``model`` (changed in place) with the media's render quality; set it before making a
    renderer, which sizes its buffers from it. Rendering only: the physics is untouched."""
    model.vis.quality.shadowsize = SHADOW_SIZE
    model.vis.quality.offsamples = MULTISAMPLES
    return model
