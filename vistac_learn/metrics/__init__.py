"""Cone metrics of the reference study plus angular metrics, numerically safe.

The study's metrics are described in docs/study.md section 6.

A configuration (object + finger placement) is pressed several times; its unit labels (r_y, r_z)
span a "cone" of force directions. Directions are compared as slopes m = y / z with z = -1 (the
force pushes into the pad, so labels have z < 0). Per configuration: m_min, m_max over the
repeats, cone mean m_mean = mean slope, width w = m_max - m_min. A prediction's slope is m.

Metrics per prediction (`per_sample_metrics`), summarised by `summarize`; `cone_metrics` does
both:
- correct y direction: sign(y_pred) lies between the smallest and the largest sign of the
  configuration's label y (signs -1, 0, +1). A cone holding both signs accepts any prediction;
  y_pred = 0 is correct only for a cone that holds y <= 0 and y >= 0 labels.
- in cone: m_min <= m <= m_max, each edge widened by a relative tolerance `IN_CONE_RTOL` * max(1,
  |edge|) so that a prediction equal to a label (up to rounding, or scaled) counts as inside.
- error = |m_edge - m| / max(|m|, EPS_M), m_edge the violated edge; 0 inside. Reported in %,
  median and mean over all predictions and over those outside the cone.
- inaccuracy to the cone edge = |m_edge - m| / w_eff (0 inside); inaccuracy to the cone mean =
  |m_mean - m| / w_eff, with w_eff = max(w, EPS_W). Reported in %, median and mean.
- MSE: the mean, over the configuration's labels and the two components, of (pred - label)^2 on
  the raw (not normalised) prediction; the torch `MSELoss` convention. Reported as the mean.
- angle to the cone mean (degrees, 0..180): between the raw prediction direction and the
  direction of slope m_mean, (y, z) ~ (-m_mean, -1).
- angular distance to the cone (degrees, 0..180): 0 inside the cone, else the angle to the nearer
  edge direction.

Conventions that keep every value finite for every finite input:
- Each vector is first reduced to its direction: divided by max(|y|, |z|), then by its length
  (no overflow for 1e308, no loss for 1e-320). Slopes and angles are therefore exactly invariant
  to a power-of-two scale and invariant up to rounding to any positive scale.
- A zero vector has no direction; it is read as (0, -1), straight into the pad: slope 0,
  angle 0.
- Slopes saturate: m = u_y / u_z on the unit vector u while u_z <= -EPS_Z (EPS_Z = 1e-6), so
  |m| <= 1 / EPS_Z = 1e6. A direction with u_z > -EPS_Z (tangential, or pointing away from the
  object, which no contact force does) gets the saturated slope -sign(u_y) / EPS_Z, y = 0
  counting as positive: it lies outside every cone whose labels press into the pad and scores
  the largest slope error. Labels are treated the same way. Angles of predictions are honest
  (unsaturated), so an away-pointing prediction lies more than 90 degrees from every cone; the
  cone edges' angles are those of their (saturated) slopes.
- |m| in the error's denominator is at least EPS_M = 1e-6: the error of y_pred -> 0 grows to
  |m_edge| * 1e6 instead of infinity (the study observed up to 35960 %).
- A cone of one label or of identical labels has w = 0; w_eff = EPS_W = 1e-3 (a cone narrower
  than 0.06 degrees at the normal counts as that wide).
- MSE clips raw components to +-MSE_CLIP = 1e100 first, so it saturates near 1e200 instead of
  overflowing.
- Medians are proper medians (`numpy.median`), never taken by a fixed index. The median or mean
  of an empty selection (e.g. no prediction outside any cone) is 0.0; the counts (`n`, `n_out`)
  tell that it was empty.
- Non-finite inputs (NaN, inf) are rejected with ValueError rather than silently propagated.

Modules: `directions` (unit directions, saturated slopes, the constants), `cone` (cones,
per-prediction metrics, summaries, `cone_metrics`), `scoring` (predictions of a model over a pair
dataset lined up with the cones, the study's table).
"""

from vistac_learn.metrics.cone import cone_metrics, cone_stats, per_sample_metrics, summarize
from vistac_learn.metrics.directions import (
    EPS_M,
    EPS_W,
    EPS_Z,
    IN_CONE_RTOL,
    MSE_CLIP,
    directions,
    slopes,
)

__all__ = [
    "EPS_Z",
    "EPS_M",
    "EPS_W",
    "IN_CONE_RTOL",
    "MSE_CLIP",
    "cone_metrics",
    "cone_stats",
    "per_sample_metrics",
    "summarize",
    "directions",
    "slopes",
]
