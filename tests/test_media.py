"""The videos' render quality (:mod:`locoman.sim.media`): cheaper, with the shadows kept."""

import mujoco

from locoman.sim.media import MULTISAMPLES, SHADOW_SIZE, media_quality

# A box hovering over a floor, lit from straight above: its shadow lies under it, seen from
# the side just beyond the box.
SCENE = """
<mujoco>
  <visual><global offwidth="64" offheight="64"/></visual>
  <worldbody>
    <light pos="0 0 3" dir="0 0 -1" castshadow="true"/>
    <geom type="plane" size="2 2 0.1" rgba="1 1 1 1"/>
    <geom type="box" pos="0 0 0.5" size="0.3 0.3 0.05" rgba="1 0 0 1"/>
    <camera name="side" pos="1.6 0 0.4" xyaxes="0 1 0 -0.25 0 1"/>
  </worldbody>
</mujoco>
"""


def _floor_where_the_shadow_falls(model: mujoco.MjModel, shadows: bool) -> float:
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    with mujoco.Renderer(model, height=64, width=64) as renderer:
        renderer.update_scene(data, camera="side")
        renderer.scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = shadows
        image = renderer.render().astype(float)
    # The floor's pixels just beyond the box, where its shadow falls.
    return image[30:36, 20:44].mean()


def test_the_media_quality_is_set_on_the_model_and_keeps_the_shadows():
    model = mujoco.MjModel.from_xml_string(SCENE)
    assert media_quality(model) is model
    assert model.vis.quality.shadowsize == SHADOW_SIZE
    assert model.vis.quality.offsamples == MULTISAMPLES
    lit = _floor_where_the_shadow_falls(model, shadows=False)
    shaded = _floor_where_the_shadow_falls(model, shadows=True)
    assert shaded < 0.8 * lit, (shaded, lit)
