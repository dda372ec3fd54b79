"""Several readings of one imprint: the classifier applied to patches across the contact.

The classifier looks at a `crop_px` window around the contact's centroid (8.4 mm at the
shipped 112 px), but an imprint on a flat face covers most of the 18 x 24 mm gel. One
label for the whole imprint paints every contact point with the material under its
centre, so a press across a material border moves the border by up to the imprint's
half-width. Reading patches of the imprint separately (each a crop centred on a point of
the contact, as the training data's crops are) gives each contact pixel the material of the
patch nearest to it, and the map a border resolved to the patch spacing.

Patch centres: the contact's centroid first, then farthest-point sampling over the contact
pixels until every contact pixel lies within `spacing_px` of a centre or `max_patches`
centres are taken.
"""

from __future__ import annotations

import numpy as np

from neuralfeels_sem.perception.touch import NO_LABEL

SAMPLE_STRIDE = 4  # farthest-point sampling runs on every 4th contact pixel (rows and columns)


def patch_centres(
    mask: np.ndarray, spacing_px: float, max_patches: int, eligible: np.ndarray | None = None
) -> np.ndarray:
    """(K, 2) (row, column) centres over a contact mask: centroid first, then farthest points.

    `eligible` (H, W) bool, optional: the pixels a centre after the first may take (e.g.
    those whose crop is mostly imprint, `crop_contact_share`); the spacing is then kept
    over the eligible contact pixels only.
    """
    if mask.ndim != 2:
        raise ValueError(f"contact mask must be (H, W), got {mask.shape}")
    if spacing_px <= 0 or max_patches < 1:
        raise ValueError(f"spacing_px={spacing_px} must be > 0 and max_patches={max_patches} >= 1")
    rows, cols = np.nonzero(mask)
    if len(rows) == 0:
        return np.zeros((0, 2))
    pixels = np.column_stack([rows, cols]).astype(np.float64)
    centres = [pixels.mean(axis=0)]
    if eligible is not None:
        if eligible.shape != mask.shape:
            raise ValueError(f"eligible {eligible.shape} must match the mask {mask.shape}")
        mask = mask & eligible
    sparse = mask[::SAMPLE_STRIDE, ::SAMPLE_STRIDE]
    r, c = np.nonzero(sparse)
    candidates = np.column_stack([r, c]).astype(np.float64) * SAMPLE_STRIDE
    if len(candidates) == 0:
        return np.array(centres)
    distance = np.linalg.norm(candidates - centres[0], axis=1)
    while len(centres) < max_patches:
        far = int(distance.argmax())
        if distance[far] <= spacing_px:
            break
        centres.append(candidates[far])
        distance = np.minimum(distance, np.linalg.norm(candidates - candidates[far], axis=1))
    return np.array(centres)


def crop_contact_share(mask: np.ndarray, crop_px: int) -> np.ndarray:
    """(H, W) share of contact pixels in the crop `crop_around` takes centred on each pixel.

    A crop centred on the imprint's rim is half empty gel, unlike the training crops
    (centred on the contact): a summed-area table gives every pixel's share in one pass.
    """
    h, w = mask.shape
    crop = min(int(crop_px), h, w)
    table = np.zeros((h + 1, w + 1), dtype=np.int64)
    table[1:, 1:] = np.cumsum(np.cumsum(mask, axis=0, dtype=np.int64), axis=1)
    y0 = np.clip(np.round(np.arange(h) - crop / 2.0).astype(np.int64), 0, h - crop)[:, None]
    x0 = np.clip(np.round(np.arange(w) - crop / 2.0).astype(np.int64), 0, w - crop)[None, :]
    inside = (
        table[y0 + crop, x0 + crop] - table[y0, x0 + crop] - table[y0 + crop, x0] + table[y0, x0]
    )
    return inside / float(crop * crop)


def crop_around(image: np.ndarray, centre: np.ndarray, crop_px: int) -> np.ndarray:
    """The `crop_px` square window centred on `centre` (row, column), kept inside the image."""
    h, w = image.shape[:2]
    crop = min(int(crop_px), h, w)
    y0 = int(np.clip(round(centre[0] - crop / 2.0), 0, h - crop))
    x0 = int(np.clip(round(centre[1] - crop / 2.0), 0, w - crop))
    return image[y0 : y0 + crop, x0 : x0 + crop]


def pixel_labels(
    shape: tuple[int, int],
    centres: np.ndarray,
    labels: np.ndarray,
    confidence: np.ndarray,
    reach_px: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Each pixel's material: the label of the nearest centre that has one, within reach.

    `labels` (K,) per centre (NO_LABEL: the patch abstained), `confidence` (K,). Returns
    (H, W) int16 labels (NO_LABEL farther than `reach_px` from every labelled centre) and
    (H, W) float32 confidences (0 there). Every pixel is labelled, not only the contact
    gate's: the map's contact points come from the tactile depth, whose contact differs
    from the gate's at its rim.
    """
    centres = np.asarray(centres, np.float64).reshape(-1, 2)
    labels = np.asarray(labels).reshape(-1)
    if len(labels) != len(centres) or len(confidence) != len(centres):
        raise ValueError(f"{len(centres)} centres but {len(labels)} labels")
    out = np.full(shape, NO_LABEL, dtype=np.int16)
    conf = np.zeros(shape, dtype=np.float32)
    read = labels != NO_LABEL
    if not read.any():
        return out, conf
    # Pixels farther than reach_px from every read centre stay unlabelled: only the box
    # around the centres is measured (half the time of the whole frame on a run's touches).
    seen = centres[read]
    r0, r1 = _span(seen[:, 0], reach_px, shape[0])
    c0, c1 = _span(seen[:, 1], reach_px, shape[1])
    rows = np.arange(r0, r1, dtype=np.float64)[:, None]
    cols = np.arange(c0, c1, dtype=np.float64)[None, :]
    # One pass per centre keeping the running nearest (the first of equals, as argmin
    # would): no (H, W, K) array, a few times faster for the few centres of a touch.
    best = np.full((r1 - r0, c1 - c0), np.inf)
    nearest = np.zeros(best.shape, dtype=np.int64)
    for k, (r, c) in enumerate(seen):
        d2 = (rows - r) ** 2 + (cols - c) ** 2
        np.putmask(nearest, d2 < best, k)
        np.minimum(best, d2, out=best)
    near = best <= reach_px**2
    out[r0:r1, c0:c1][near] = labels[read][nearest[near]]
    conf[r0:r1, c0:c1][near] = np.asarray(confidence, np.float32)[read][nearest[near]]
    return out, conf


def _span(values: np.ndarray, reach: float, size: int) -> tuple[int, int]:
    """The index range [lo, hi) of an axis within `reach` of any of `values`, inside 0..size."""
    lo = max(int(np.floor(values.min() - reach)), 0)
    hi = min(int(np.ceil(values.max() + reach)) + 1, size)
    return lo, hi
