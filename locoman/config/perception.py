"""Typed configuration of the perception front half (paper A, Sec. III-A.1 and III-A.2).

Sections: ``perception.generate`` (images R_g and sim views R_s, D_s), ``perception.masks``
(object masks, human keypoints and pose), ``perception.clouds`` (depth, intrinsics, lifting)
and ``perception.depth_error`` (the error model standing in for a metric-depth network).
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

GENERATE_BACKENDS = ("render", "flux", "folder")
MASK_BACKENDS = ("render", "grabcut", "sam")
KEYPOINT_BACKENDS = ("render", "mediapipe", "annotated")
POSE_BACKENDS = ("truth_noise", "fit")
DEPTH_BACKENDS = ("error_model", "depth_anything", "provided")
INTRINSICS = ("heuristic", "true")
TORCH_DTYPES = ("float32", "bfloat16", "float16")


def _range(name: str, values: list[float], lo: float, hi: float) -> list[tuple[str, str]]:
    if len(values) != 2 or not lo <= values[0] <= values[1] <= hi:
        return [(name, f"needs [min, max] with {lo} <= min <= max <= {hi}, got {values}")]
    return []


def _choice(name: str, value: str, allowed: tuple[str, ...]) -> list[tuple[str, str]]:
    return [] if value in allowed else [(name, f"must be one of {list(allowed)}, got {value!r}")]


@dataclass
class VariantCfg:
    """How far the object in a generated image departs from the scene's object.

    An image generator never draws the exact object of the scene; the ``render`` backend
    draws a variant so that contact transfer faces the same intra-class gap (paper A, III-A.2).

    Attributes:
        size_scale: Range of the uniform scale factor [-].
        aspect_jitter: Largest extra relative change of each extent on its own [-].
        colour_jitter: Largest change of each RGB channel [-].
        texture_probability: Chance that the variant gets a checker texture [-].
    """

    size_scale: list[float] = field(default_factory=lambda: [0.85, 1.15])
    aspect_jitter: float = 0.1
    colour_jitter: float = 0.25
    texture_probability: float = 0.3

    def check(self) -> list[tuple[str, str]]:
        errors = _range("size_scale", self.size_scale, 0.2, 5.0)
        if not 0.0 <= self.aspect_jitter < 0.5:
            errors.append(("aspect_jitter", f"must be in [0, 0.5), got {self.aspect_jitter}"))
        if not 0.0 <= self.colour_jitter <= 1.0:
            errors.append(("colour_jitter", f"must be in [0, 1], got {self.colour_jitter}"))
        if not 0.0 <= self.texture_probability <= 1.0:
            errors.append(("texture_probability", "must be in [0, 1]"))
        return errors


@dataclass
class ViewCfg:
    """Camera, light and demonstrator placement of a generated image, drawn per seed.

    Attributes:
        fovy_deg: Range of the vertical field of view [deg]; the true focal length is unknown
            to the pipeline, as for a generated image.
        azimuth_deg: Range of the camera's angle from the person's facing direction [deg];
            the side (left or right) is drawn too.
        elevation_deg: Range of the camera's angle above the horizon [deg].
        margin: Fraction of the image kept free around the person and the object [-].
        light_diffuse: Range of the key light's diffuse intensity [-].
        standoff_m: Range of the distance between the feet and the hands along the person's
            facing direction when both hands act [m].
        lateral_jitter_m: Largest sideways offset of the person [m].
        yaw_jitter_deg: Largest rotation of the person about the hands' midpoint [deg].
    """

    fovy_deg: list[float] = field(default_factory=lambda: [40.0, 60.0])
    azimuth_deg: list[float] = field(default_factory=lambda: [55.0, 100.0])
    elevation_deg: list[float] = field(default_factory=lambda: [8.0, 25.0])
    margin: float = 0.08
    light_diffuse: list[float] = field(default_factory=lambda: [0.45, 0.8])
    standoff_m: list[float] = field(default_factory=lambda: [0.3, 0.38])
    lateral_jitter_m: float = 0.04
    yaw_jitter_deg: float = 8.0

    def check(self) -> list[tuple[str, str]]:
        errors = _range("fovy_deg", self.fovy_deg, 10.0, 120.0)
        errors += _range("azimuth_deg", self.azimuth_deg, 0.0, 180.0)
        errors += _range("elevation_deg", self.elevation_deg, -30.0, 80.0)
        errors += _range("light_diffuse", self.light_diffuse, 0.0, 1.0)
        errors += _range("standoff_m", self.standoff_m, 0.1, 1.0)
        if not 0.0 <= self.margin < 0.4:
            errors.append(("margin", f"must be in [0, 0.4), got {self.margin}"))
        return errors


@dataclass
class SimViewCfg:
    """The simulated RGB-D view R_s, D_s of the subtask's object (true intrinsics).

    Attributes:
        width: [px].
        height: [px].
        fovy_deg: Vertical field of view [deg].
        azimuth_deg: Camera angle from the object's -x (approach) side, towards +y [deg].
        elevation_deg: Camera angle above the horizon [deg].
        fill: Fraction of the image height the object's bounding sphere spans [-].
    """

    width: int = 512
    height: int = 512
    fovy_deg: float = 45.0
    azimuth_deg: float = 55.0
    elevation_deg: float = 30.0
    fill: float = 0.55

    def check(self) -> list[tuple[str, str]]:
        errors = []
        if not (32 <= self.width <= 4096 and 32 <= self.height <= 4096):
            errors.append(("width", "image size must be within [32, 4096] px"))
        if not 0.05 <= self.fill <= 1.0:
            errors.append(("fill", f"must be in [0.05, 1], got {self.fill}"))
        return errors


@dataclass
class TorchCfg:
    """Where a learned model runs.

    Attributes:
        device: torch device: ``cpu``, ``cuda`` or ``cuda:<index>``; asking for CUDA where
            torch sees none is an error, never a silent fall back to the CPU.
        dtype: Precision of the weights and inputs: ``float32``, ``bfloat16`` or
            ``float16`` (CUDA only: many CPU kernels have no float16).
    """

    device: str = "cpu"
    dtype: str = "float32"

    def check(self) -> list[tuple[str, str]]:
        errors = _choice("dtype", self.dtype, TORCH_DTYPES)
        if not re.fullmatch(r"cpu|cuda(:\d+)?", self.device):
            errors.append(("device", f"must be cpu, cuda or cuda:<index>, got {self.device!r}"))
        elif self.dtype == "float16" and self.device == "cpu":
            errors.append(("dtype", "float16 runs on CUDA only; use bfloat16 or float32 on cpu"))
        return errors


@dataclass
class FluxCfg:
    """The ``flux`` image backend: a diffusers pipeline loaded from a local folder.

    Attributes:
        weights_dir: Folder holding the pipeline (``model_index.json`` and components), e.g.
            a local copy of FLUX.1-schnell. Nothing is downloaded.
        steps: Denoising steps.
        guidance_scale: Classifier-free guidance [-].
        max_sequence_length: Prompt tokens the T5 encoder reads (FLUX.1-schnell: <= 256).
        runtime: Device and precision.
    """

    weights_dir: str | None = None
    steps: int = 4
    guidance_scale: float = 0.0
    max_sequence_length: int = 256
    runtime: TorchCfg = field(default_factory=TorchCfg)

    def check(self) -> list[tuple[str, str]]:
        errors = [] if self.steps >= 1 else [("steps", "must be >= 1")]
        if not 1 <= self.max_sequence_length <= 512:
            errors.append(("max_sequence_length", "must be within [1, 512] tokens"))
        return errors


@dataclass
class FolderCfg:
    """The ``folder`` image backend: R_g from a folder of the user's images.

    Attributes:
        images_dir: Folder holding ``subtask_<i>.png`` (or ``.jpg``) per subtask of the plan,
            optionally ``subtask_<i>.json`` (the object's box, 2D keypoints) and
            ``subtask_<i>_depth.png`` (16-bit depth [mm]); see
            :mod:`locoman.perception.user_images`. A relative path is taken from the
            repository root. Nothing about the folder's location enters the artifacts.
    """

    images_dir: str | None = None


@dataclass
class GenerateCfg:
    """Stage ``generate``: an image R_g per subtask and the sim views R_s, D_s.

    Attributes:
        backend: ``render`` (posed demonstrator rendered in MuJoCo, the CPU default),
            ``flux`` (a diffusion model from ``flux.weights_dir``) or ``folder`` (the user's
            images from ``folder.images_dir``).
        width: Image width [px].
        height: Image height [px].
        step_height_max_m: Feet stand on the object's top when it is at most this high [m];
            higher objects are walked to, feet on the floor.
    """

    backend: str = "render"
    width: int = 512
    height: int = 512
    step_height_max_m: float = 0.45
    variant: VariantCfg = field(default_factory=VariantCfg)
    view: ViewCfg = field(default_factory=ViewCfg)
    sim_view: SimViewCfg = field(default_factory=SimViewCfg)
    flux: FluxCfg = field(default_factory=FluxCfg)
    folder: FolderCfg = field(default_factory=FolderCfg)

    def check(self) -> list[tuple[str, str]]:
        errors = _choice("backend", self.backend, GENERATE_BACKENDS)
        if self.backend == "folder" and not self.folder.images_dir:
            errors.append(("folder.images_dir", "the folder backend needs the images' folder"))
        if not (64 <= self.width <= 4096 and 64 <= self.height <= 4096):
            errors.append(("width", "image size must be within [64, 4096] px"))
        return errors


@dataclass
class MasksCfg:
    """Stage ``masks``: object masks in R_g and R_s, human keypoints and 3D pose in R_g.

    Attributes:
        backend: ``render`` (segmentation from the renderer), ``grabcut`` (OpenCV, seeded
            by a box) or ``sam`` (a SAM checkpoint from ``sam_weights_dir``).
        box_margin_px: Margin added around the object's box that seeds ``grabcut`` and
            ``sam`` [px]; the box stands in for the paper's open-vocabulary detector.
        grabcut_iterations: GrabCut iterations.
        sam_weights_dir: Folder of a transformers SAM checkpoint (``config.json`` and weights).
        sam_runtime: Device and precision of SAM.
        keypoints: ``render`` (true keypoints plus ``keypoint_jitter_px``), ``mediapipe``
            (BlazePose, needs the optional ``mediapipe`` package) or ``annotated`` (the
            ``keypoints_px`` of the ``folder`` backend's annotations).
        pose: The 3D human pose: ``truth_noise`` (the true pose plus ``pose_noise_*``,
            render images only) or ``fit`` (the human model fitted to the 2D keypoints through
            paper A's heuristic intrinsics, :mod:`locoman.perception.pose_fit`). Both are
            scored against the truth where there is one.
        keypoint_jitter_px: Std of the Gaussian pixel noise on each keypoint [px].
        pose_noise_m: Std of the noise on the 3D keypoints of the pose artifact [m],
            standing in for a 3D human pose estimator.
        pose_noise_rad: Std of the noise on the human joint angles of the pose artifact [rad].
    """

    backend: str = "render"
    box_margin_px: int = 8
    grabcut_iterations: int = 5
    sam_weights_dir: str | None = None
    sam_runtime: TorchCfg = field(default_factory=TorchCfg)
    keypoints: str = "render"
    pose: str = "truth_noise"
    keypoint_jitter_px: float = 3.0
    pose_noise_m: float = 0.01
    pose_noise_rad: float = 0.05

    def check(self) -> list[tuple[str, str]]:
        errors = _choice("backend", self.backend, MASK_BACKENDS)
        errors += _choice("keypoints", self.keypoints, KEYPOINT_BACKENDS)
        errors += _choice("pose", self.pose, POSE_BACKENDS)
        if self.keypoint_jitter_px < 0 or self.pose_noise_m < 0 or self.pose_noise_rad < 0:
            errors.append(("keypoint_jitter_px", "noise levels must be >= 0"))
        if self.box_margin_px < 0 or self.grabcut_iterations < 1:
            errors.append(("box_margin_px", "margin must be >= 0 px and iterations >= 1"))
        return errors


@dataclass
class DepthErrorCfg:
    """Error model on the true depth of R_g, standing in for a monocular metric-depth network.

    Attributes:
        scale: Global scale factor applied to the depth [-] (metric-depth models are off by
            a few percent).
        noise_std_m: Std of additive Gaussian noise [m].
        edge_dropout_px: Pixels within this distance of a depth discontinuity are dropped.
        edge_jump_m: A neighbour depth change above this counts as a discontinuity [m].
    """

    scale: float = 1.05
    noise_std_m: float = 0.01
    edge_dropout_px: int = 2
    edge_jump_m: float = 0.05

    def check(self) -> list[tuple[str, str]]:
        errors = []
        if not 0.1 <= self.scale <= 10.0:
            errors.append(("scale", f"must be in [0.1, 10], got {self.scale}"))
        if self.noise_std_m < 0 or self.edge_dropout_px < 0 or self.edge_jump_m <= 0:
            errors.append(("noise_std_m", "noise and dropout must be >= 0, edge_jump_m > 0"))
        return errors


@dataclass
class CloudsCfg:
    """Stage ``clouds``: depth and intrinsics of R_g, object clouds, lifted keypoints.

    Attributes:
        depth: ``error_model`` (true depth through ``perception.depth_error``),
            ``depth_anything`` (a transformers depth-estimation checkpoint) or ``provided``
            (the depth maps of the ``folder`` backend's images).
        depth_weights_dir: Folder of the depth checkpoint for ``depth_anything``.
        depth_runtime: Device and precision of the depth model.
        intrinsics: ``heuristic`` (the paper: focal lengths = image resolution, principal
            point = half of it) or ``true`` (the renderer's, for ablation).
        outlier_neighbours: Neighbours of the statistical outlier removal (the point included).
        outlier_std_ratio: Std ratio of the statistical outlier removal [-].
        voxel_m: Voxel size of the down-sampled clouds [m].
        min_points: Fewer object points than this is an error [-].
    """

    depth: str = "error_model"
    depth_weights_dir: str | None = None
    depth_runtime: TorchCfg = field(default_factory=TorchCfg)
    intrinsics: str = "heuristic"
    outlier_neighbours: int = 20
    outlier_std_ratio: float = 2.0
    voxel_m: float = 0.005
    min_points: int = 50

    def check(self) -> list[tuple[str, str]]:
        errors = _choice("depth", self.depth, DEPTH_BACKENDS)
        errors += _choice("intrinsics", self.intrinsics, INTRINSICS)
        if self.outlier_neighbours < 1 or self.outlier_std_ratio <= 0:
            errors.append(("outlier_neighbours", "needs >= 1 neighbours and a std ratio > 0"))
        if self.voxel_m < 0 or self.min_points < 3:
            errors.append(("voxel_m", "voxel must be >= 0 m and min_points >= 3"))
        return errors


@dataclass
class PerceptionCfg:
    """The perception front half of the humanoid branch.

    Attributes:
        scenarios: Scenarios whose plans go through perception (their robot must be the G1).
    """

    scenarios: list[str] = field(default_factory=lambda: ["tiny", "s1_basket", "s2_trolley"])
    generate: GenerateCfg = field(default_factory=GenerateCfg)
    masks: MasksCfg = field(default_factory=MasksCfg)
    clouds: CloudsCfg = field(default_factory=CloudsCfg)
    depth_error: DepthErrorCfg = field(default_factory=DepthErrorCfg)
