"""How far a registration can be trusted, from what a user has: no ground truth.

Contact transfer's registration (:mod:`locoman.contact.registration`) keeps the hypothesis
with the best overlap; a wrong one can still overlap well (a basket turned a quarter turn
shows the same walls). Three signals, each computed from the images and the clouds alone:

- ``overlap``: the winner's overlap F-score (its cloud on the object's surface, and the
  surface the camera sees covered by the cloud);
- ``margin``: how far the winner's overlap beats the best hypothesis that places the cloud
  *otherwise* (its points moved by more than ``distinct_fraction`` of the object's size, in
  the median) and passes the same gates (upright, the person facing its approach side).
  Poses that the object's own symmetry makes the same
  (a box turned by half a turn) still move the cloud, and the hands with it, to its other
  side: they count as other poses, which the person's facing tells apart;
- ``silhouette_iou``: the object's silhouette drawn in R_g through the winner against the
  object's mask in R_g: a registration that fits the depth cloud but not the picture;
- ``contact_gaps_m``: how far each contact the winner places had to move to touch the
  object (:func:`locoman.contact.transfer.contact_gaps`): a hand holds the object, so a
  pose that puts the hand a handspan off it is wrong where the hand is, however well the
  clouds overlap (a trolley's thin handle bar weighs nothing in the overlap).

A registration is *doubtful* when any falls below its threshold (``contacts.confidence``);
``contacts.on_doubt`` decides what the stage does then (:mod:`locoman.contact.pipeline`).
"""

from __future__ import annotations

import dataclasses

import numpy as np
from scipy import ndimage

from locoman.config.contacts import ConfidenceCfg
from locoman.contact.kabsch import apply
from locoman.contact.registration import Registration, Surface, View


@dataclasses.dataclass(frozen=True)
class Confidence:
    """A registration's confidence (see the module).

    Attributes:
        overlap: The winner's overlap F-score, in [0, 1].
        runner_up: The best overlap of a hypothesis that places the cloud otherwise and
            passes the gates (0 when none does).
        rival: The same among every hypothesis, gated or not: how far the geometry alone
            tells the poses apart.
        margin: ``overlap - runner_up`` [-].
        silhouette_iou: IoU of the registered object's silhouette with R_g's mask, in [0, 1].
        contact_gaps_m: Per effector, how far its contact moved onto the object [m].
        doubtful: Some signal is below its threshold.
        reasons: Which, with their values.
    """

    overlap: float
    runner_up: float
    rival: float
    margin: float
    silhouette_iou: float
    contact_gaps_m: dict[str, float]
    doubtful: bool
    reasons: tuple[str, ...]

    def as_dict(self) -> dict[str, object]:
        return dataclasses.asdict(self) | {"reasons": list(self.reasons)}


def cloud_moved(a: np.ndarray, b: np.ndarray, source: np.ndarray) -> np.ndarray:
    """How far [m] (H,) each of the transforms ``a`` (H, 4, 4) puts the source cloud (N, 3)
    from where ``b`` (4, 4) puts it: the median distance of a point's two images. The hands
    go where the cloud goes, so two hypotheses that place the cloud alike place the contacts
    alike; a box turned by half a turn about its own axis fits its surface as well but puts
    the cloud, and the person, on its other side."""
    there = apply(b[None], source[None])[0]
    return np.median(np.linalg.norm(apply(a, source) - there, axis=2), axis=1)


def silhouette_iou(
    surface: Surface, transform: np.ndarray, view: View, mask: np.ndarray, radius_px: int
) -> float:
    """IoU of the object's silhouette in R_g, its surface samples mapped into R_g's camera by
    the inverse of ``transform`` (4, 4) and drawn ``radius_px`` wide, with ``mask`` (H, W)."""
    metric = apply(np.linalg.inv(transform)[None], surface.points[None])[0]
    lifted = metric * view.scale + view.offset
    ahead = lifted[:, 2] > 1e-9
    pixel = lifted[ahead, :2] @ view.K[:2, :2].T / lifted[ahead, 2:3] + view.K[:2, 2]
    rows, cols = mask.shape
    u, v = np.floor(pixel[:, 0]).astype(int), np.floor(pixel[:, 1]).astype(int)
    inside = (u >= 0) & (u < cols) & (v >= 0) & (v < rows)
    drawn = np.zeros_like(mask, dtype=bool)
    drawn[v[inside], u[inside]] = True
    drawn = ndimage.binary_dilation(drawn, iterations=radius_px)
    drawn = ndimage.binary_fill_holes(drawn)
    union = np.logical_or(drawn, mask).sum()
    return float(np.logical_and(drawn, mask).sum() / union) if union else 0.0


def confidence(
    reg: Registration,
    surface: Surface,
    source: np.ndarray,
    view: View | None,
    mask: np.ndarray,
    cfg: ConfidenceCfg,
    contact_gaps_m: dict[str, float],
) -> Confidence:
    """The confidence of ``reg`` (see the module), from the source cloud (N, 3) of R_g in its
    metric camera frame, the object's ``surface``, R_g's ``view`` and object ``mask``, and how
    far [m] each effector's contact moved onto the object."""
    flat = reg.candidates.reshape(-1, 4, 4)
    best = flat[np.ravel_multi_index((reg.iteration - 1, reg.turn), reg.overlaps.shape)]
    size = float(np.linalg.norm(np.ptp(surface.points, axis=0)))
    moved = cloud_moved(flat, best, source)
    distinct = moved > cfg.distinct_fraction * size
    overlaps = reg.overlaps.ravel()
    otherwise = distinct & reg.gated.ravel()
    runner_up = float(overlaps[otherwise].max()) if otherwise.any() else 0.0
    rival = float(overlaps[distinct].max()) if distinct.any() else 0.0
    iou = silhouette_iou(surface, best, view, mask, cfg.silhouette_radius_px) if view else 1.0
    margin = reg.overlap - runner_up
    reasons = []
    if reg.overlap < cfg.min_overlap:
        reasons.append(f"overlap {reg.overlap:.2f} < {cfg.min_overlap}")
    if margin < cfg.min_margin:
        reasons.append(f"margin {margin:.3f} over another pose < {cfg.min_margin}")
    if iou < cfg.min_silhouette_iou:
        reasons.append(f"silhouette IoU {iou:.2f} < {cfg.min_silhouette_iou}")
    for effector, gap in contact_gaps_m.items():
        if gap > cfg.max_contact_gap_m:
            reasons.append(
                f"{effector} lands {100 * gap:.1f} cm off the object > {cfg.max_contact_gap_m} m"
            )
    gaps = {e: float(g) for e, g in contact_gaps_m.items()}
    return Confidence(
        reg.overlap, runner_up, rival, margin, iou, gaps, bool(reasons), tuple(reasons)
    )
