"""Typed configuration of contact transfer (paper A, Sec. III-A.2, third step; Sec. V-B).

Section ``contacts``: the semantic score pool, the sampled SVD + ICP registration, how the
hands and feet are lifted to 3D, and the method (``registration`` or the paper's
geometry-unaware ``naive`` baseline), so that the contact ablation is a parameter change.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from locoman.config.cost import at_most
from locoman.config.perception import _choice, _range

METHODS = ("registration", "naive")
DESCRIPTORS = ("sift", "learned")
TRANSFORMS = ("rigid", "similarity")
LIFTS = ("depth", "pose")


@dataclass
class PoolCfg:
    """The semantic score pool: for each point sampled on the object in R_g, the top-N most
    plausible matches on the object in R_s, with their scores.

    Attributes:
        descriptor: ``sift`` (dense SIFT plus the position in the object's box, on the CPU)
            or ``learned`` (a TorchScript feature extractor from ``weights_file``, e.g. an
            exported DINOv2 or SD+DINO backbone).
        weights_file: TorchScript file of the ``learned`` backend; nothing is downloaded.
        points: Points sampled on the object's mask in R_g [-].
        top_n: Matches kept per sampled point [-].
        grid_px: Spacing of the candidate grid in R_s [px].
        patch_fraction: SIFT patch size as a fraction of the object's size in the image [-].
        layout_weight: Weight of the position inside the object's box against appearance [-].
    """

    descriptor: str = "sift"
    weights_file: str | None = None
    points: int = 64
    top_n: int = 5
    grid_px: int = 4
    patch_fraction: float = 0.3
    layout_weight: float = 1.0

    def check(self) -> list[tuple[str, str]]:
        errors = _choice("descriptor", self.descriptor, DESCRIPTORS)
        if self.points < 3 or self.top_n < 1 or self.grid_px < 1:
            errors.append(("points", "needs points >= 3, top_n >= 1 and grid_px >= 1"))
        if not 0.02 <= self.patch_fraction <= 1.0:
            errors.append(("patch_fraction", f"must be in [0.02, 1], got {self.patch_fraction}"))
        if self.layout_weight < 0.0:
            errors.append(("layout_weight", "must be >= 0"))
        errors += at_most("points", self.points, 4096, "matching is quadratic in the points")
        errors += at_most("top_n", self.top_n, self.points, "at most every sampled point")
        return errors


@dataclass
class RegistrationCfg:
    """Sampling-based registration: SVD on sampled matches, ICP, keep the best overlap.

    Attributes:
        iterations: Hypotheses drawn from the pool (paper: 10); the first takes every top-1.
        transform: ``rigid`` (Kabsch) or ``similarity`` (Umeyama, with a scale, since the
            generated image's depth and intrinsics are off by a factor).
        scale_range: The similarity's scale is clamped to this range [-].
        trim_rounds: Refits of the SVD on the half of the matches that fit best; 0 is the
            paper's single SVD.
        symmetry_turns: Each hypothesis is also tried turned by 360/turns degrees about the
            object's vertical axis (4: boxes and tables; 1: no turns).
        upright: ICP keeps each levelled hypothesis upright and only turns it about the
            vertical (objects stand upright on the person's ground plane).
        max_tilt_deg: Hypotheses that tilt the person's ground plane further than this from
            the horizontal are dropped (objects stand upright) [deg].
        max_facing_deg: Hypotheses that turn the object's approach side (+x) further than
            this from the person's facing are dropped; the object is symmetric, the person's
            facing is not [deg].
        model_points: Samples of the simulated object's surface [-].
        icp_points: The R_g cloud is thinned to this many points for ICP [-].
        icp_iterations: ICP iterations per hypothesis.
        icp_distance: ICP pairs longer than this fraction of the object's size are dropped.
        overlap_distance: A point overlaps the other cloud within this fraction of the
            object's size [-].
        occlusion_margin_m: A camera-facing surface point counts as hidden, and is not
            asked to have a source point, where D_g at its pixel in R_g is nearer by more
            than this (the person's arm in front of the box) [m]; null: none is hidden.
        stretch_iterations: ICP iterations with a scale per object axis after the winner is
            chosen (0: keep the similarity) [-].
        max_stretch: Each axis' factor stays within 1 +- this [-].
        stretch_prior_m: Pulls each factor towards 1 like a spread of this many metres seen
            at scale 1, so a barely seen axis keeps the similarity's scale [m].
    """

    iterations: int = 10
    transform: str = "similarity"
    scale_range: list[float] = field(default_factory=lambda: [0.8, 1.25])
    trim_rounds: int = 2
    symmetry_turns: int = 4
    max_tilt_deg: float = 20.0
    upright: bool = True
    max_facing_deg: float = 45.0
    model_points: int = 3000
    icp_points: int = 600
    icp_iterations: int = 30
    icp_distance: float = 0.15
    overlap_distance: float = 0.03
    occlusion_margin_m: float | None = 0.05
    stretch_iterations: int = 20
    max_stretch: float = 0.15
    stretch_prior_m: float = 0.02

    def check(self) -> list[tuple[str, str]]:
        errors = _choice("transform", self.transform, TRANSFORMS)
        errors += _range("scale_range", self.scale_range, 0.05, 20.0)
        if self.iterations < 1 or self.icp_iterations < 1 or self.trim_rounds < 0:
            errors.append(("iterations", "needs iterations, icp_iterations >= 1, trims >= 0"))
        if not 0.0 < self.max_tilt_deg <= 180.0:
            errors.append(("max_tilt_deg", f"must be in (0, 180], got {self.max_tilt_deg}"))
        if self.symmetry_turns < 1 or not 0.0 < self.max_facing_deg <= 180.0:
            errors.append(("symmetry_turns", "needs turns >= 1 and max_facing_deg in (0, 180]"))
        if not (0.0 < self.icp_distance <= 2.0 and 0.0 < self.overlap_distance <= 1.0):
            errors.append(("icp_distance", "distances are fractions of the object size > 0"))
        if self.stretch_iterations < 0 or not 0.0 <= self.max_stretch < 1.0:
            errors.append(("max_stretch", "needs stretch_iterations >= 0, max_stretch in [0, 1)"))
        if self.occlusion_margin_m is not None and self.occlusion_margin_m <= 0.0:
            errors.append(("occlusion_margin_m", "must be > 0, or null for no occlusion test"))
        if self.stretch_prior_m < 0.0:
            errors.append(("stretch_prior_m", "must be >= 0"))
        if self.model_points < 100 or self.icp_points < 10:
            errors.append(("model_points", "needs model_points >= 100 and icp_points >= 10"))
        errors += at_most("model_points", self.model_points, 100_000, "each ICP step queries all")
        errors += at_most("icp_points", self.icp_points, 20_000, "a KD-tree query per point")
        errors += at_most("iterations", self.iterations, 1000, "each one runs a whole ICP")
        errors += at_most("icp_iterations", self.icp_iterations, 1000, "ICP converges in ~30")
        errors += at_most("symmetry_turns", self.symmetry_turns, 36, "each turn is one more ICP")
        return errors


@dataclass
class ConfidenceCfg:
    """When a registration is doubtful (:mod:`locoman.contact.confidence`).

    Attributes:
        min_overlap: The winner's overlap F-score below which it is doubtful [-].
        min_margin: How far the winner's overlap must beat the best hypothesis that places
            the cloud otherwise [-].
        min_silhouette_iou: IoU of the registered object's silhouette with R_g's mask [-].
        distinct_fraction: A hypothesis places the cloud otherwise when it moves its points
            by more than this fraction of the object's size (median) [-].
        silhouette_radius_px: Radius each surface sample is drawn with in R_g [px].
        max_contact_gap_m: A contact the registration places farther than this from the
            object's surface (a foot: horizontally) makes it doubtful [m].
    """

    min_overlap: float = 0.5
    min_margin: float = 0.02
    min_silhouette_iou: float = 0.5
    distinct_fraction: float = 0.1
    silhouette_radius_px: int = 3
    max_contact_gap_m: float = 0.06

    def check(self) -> list[tuple[str, str]]:
        errors = []
        for name in ("min_overlap", "min_margin", "min_silhouette_iou", "distinct_fraction"):
            if not 0.0 <= getattr(self, name) <= 1.0:
                errors.append((name, f"must be in [0, 1], got {getattr(self, name)}"))
        if not 0.0 < self.max_contact_gap_m <= 1.0:
            errors.append(
                ("max_contact_gap_m", f"must be in (0, 1] m, got {self.max_contact_gap_m}")
            )
        if not 0 <= self.silhouette_radius_px <= 50:
            errors.append(("silhouette_radius_px", "must be in [0, 50] px"))
        return errors


ON_DOUBT = ("warn", "fail", "fallback")


@dataclass
class ContactsCfg:
    """Stage ``contacts``: contact locations L on the simulated objects and the human's
    placement relative to the object.

    Attributes:
        method: ``registration`` (the paper's method) or ``naive`` (the top-1 semantic match
            of each contact, no registration: the geometry-unaware baseline of Sec. V-B).
        lift: ``depth`` (the paper: the 2D hand and foot keypoints lifted with D_g) or
            ``pose`` (the 3D pose estimate anchored to D_g at its visible keypoints, which
            also places hands hidden behind the object).
        anchor_quantile: Quantile of the keypoints' depth ratios (lifted / pose) taken as
            the anchor's depth scale; high, because occluders and the body's surface only
            make the lifted depth nearer [-].
        confidence: When a registration is doubtful.
        on_doubt: What a doubtful registration does: ``warn`` (a warning naming the
            subtask; its contacts are used), ``fail`` (the stage stops, naming it) or
            ``fallback`` (the naive contacts of Sec. V-B replace its contacts).
    """

    method: str = "registration"
    lift: str = "pose"
    anchor_quantile: float = 0.9
    pool: PoolCfg = field(default_factory=PoolCfg)
    registration: RegistrationCfg = field(default_factory=RegistrationCfg)
    confidence: ConfidenceCfg = field(default_factory=ConfidenceCfg)
    on_doubt: str = "warn"

    def check(self) -> list[tuple[str, str]]:
        errors = _choice("method", self.method, METHODS)
        errors += _choice("on_doubt", self.on_doubt, ON_DOUBT)
        errors += _choice("lift", self.lift, LIFTS)
        if not 0.0 <= self.anchor_quantile <= 1.0:
            errors.append(("anchor_quantile", f"must be in [0, 1], got {self.anchor_quantile}"))
        return errors
