"""TPS-RPM point matching (Chui & Rangarajan 2003; their MATLAB demo ``cMIX.m``).

See docs/algorithms/tps-rpm.md#algorithm. The template (K points) is warped onto the data (N points)
by deterministic
annealing: at each temperature a softassign correspondence with outlier slack is computed, the
template is attracted to the "virtual targets" it implies, and a regularised thin-plate spline is
refitted. The settings, the normalisation, the temperature schedules and the template
prepared once for many runs live in :mod:`trackfw_plugins.maths.tps_rpm_template`.

The annealing loop itself (compiled, or numpy with the symmetry-breaking noise) is
:mod:`trackfw_plugins.maths.tps_rpm_annealing` (docs/algorithms/tps-rpm.md#speed); this module
normalises, batches the data sets by template and fits the final TPS.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from trackfw.arrays import FloatArray, IntArray
from trackfw_plugins.maths.thin_plate import homogeneous, tps_kernel
from trackfw_plugins.maths.tps_rpm_annealing import anneal
from trackfw_plugins.maths.tps_rpm_template import (
    TpsRpmSettings,
    TpsRpmTemplate,
    code_temperatures,
    paper_temperatures,
)


@dataclass
class TpsRpmResult:
    """Output of one TPS-RPM run.

    Attributes:
        correspondence: (K, N) final softassign matrix H (without slack).
        matches: (M, 2) int pairs (template_index, data_index) from the thresholded H.
        bending_energy: φ(f) in normalised coordinates (0 for affine maps and K <= 3).
        warped_template: (K, 2) f(template) in image coordinates.
        nonaffine: (K, 3) TPS coefficients c (normalised coordinates).
        affine: (3, 3) affine part d (normalised coordinates).
    """

    correspondence: FloatArray
    matches: IntArray
    bending_energy: float
    warped_template: FloatArray
    nonaffine: FloatArray
    affine: FloatArray
    template_centre: FloatArray = field(repr=False)
    template_scale: float = field(repr=False)
    data_centre: FloatArray = field(repr=False)
    data_scale: float = field(repr=False)
    normalised_template: FloatArray = field(repr=False)

    def transform(self, points: FloatArray) -> FloatArray:
        """Map any image points (P, 2) through f; returns (P, 2) image coordinates."""
        points = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        normalised = (points - self.template_centre) / self.template_scale
        mapped = (
            homogeneous(normalised) @ self.affine
            + tps_kernel(normalised, self.normalised_template) @ self.nonaffine
        )
        return self.data_centre + self.data_scale * mapped[:, 1:3]


def threshold_matches(correspondence: FloatArray, threshold: float = 0.5) -> IntArray:
    """One-to-one pairs of a correspondence matrix (docs/algorithms/tps-rpm.md#outputs).

    A pair (p, q) is kept when h_pq > threshold and h_pq is the largest entry of row p and of
    column q.

    Args:
        correspondence: (K, N) matrix.
        threshold: minimal entry.

    Returns:
        (M, 2) int array of (template_index, data_index), sorted by template index.

    >>> threshold_matches(np.array([[0.9, 0.05], [0.6, 0.3]]))
    array([[0, 0]])
    """
    rows, columns = correspondence.shape
    if rows == 0 or columns == 0:
        return np.zeros((0, 2), dtype=np.int64)
    best_column = np.argmax(correspondence, axis=1)
    best_row = np.argmax(correspondence, axis=0)
    template_index = np.arange(rows)
    keep = (correspondence[template_index, best_column] > threshold) & (
        best_row[best_column] == template_index
    )
    return np.stack([template_index[keep], best_column[keep]], axis=1).astype(np.int64)


@dataclass
class TpsRpmBatch:
    """Array outputs of a batch of TPS-RPM runs (B data sets of N points, K template points).

    Attributes:
        correspondence: (B, K, N) final H.
        matched: (B, K) data index matched to each template point, -1 when none.
        bending_energy: (B,) φ in normalised coordinates.
        warped_template: (B, K, 2) f(template) in image coordinates.
        nonaffine: (B, K, 3) c; affine: (B, 3, 3) d (normalised coordinates).
        data_centre: (B, 2); data_scale: (B,) data normalisation.
        owner: (B,) template index of each run.
    """

    correspondence: FloatArray
    matched: IntArray
    bending_energy: FloatArray
    warped_template: FloatArray
    nonaffine: FloatArray
    affine: FloatArray
    data_centre: FloatArray
    data_scale: FloatArray
    owner: IntArray

    def result(self, index: int, templates: Sequence[TpsRpmTemplate]) -> TpsRpmResult:
        """The :class:`TpsRpmResult` of run ``index``."""
        prepared = templates[int(self.owner[index])]
        row = self.matched[index]
        matches = np.stack([np.nonzero(row >= 0)[0], row[row >= 0]], axis=1).astype(np.int64)
        return TpsRpmResult(
            correspondence=self.correspondence[index],
            matches=matches.reshape(-1, 2),
            bending_energy=float(self.bending_energy[index]),
            warped_template=self.warped_template[index],
            nonaffine=self.nonaffine[index],
            affine=self.affine[index],
            template_centre=prepared.centre,
            template_scale=prepared.scale,
            data_centre=self.data_centre[index],
            data_scale=float(self.data_scale[index]),
            normalised_template=prepared.normalised,
        )


def batch_matches(correspondence: FloatArray, threshold: float) -> IntArray:
    """Vectorised :func:`threshold_matches`: (B, K, N) -> (B, K) data index or -1."""
    batch, rows, columns = correspondence.shape
    if rows == 0 or columns == 0:
        return np.full((batch, rows), -1, dtype=np.int64)
    best_column = np.argmax(correspondence, axis=2)  # (B, K)
    best_row = np.argmax(correspondence, axis=1)  # (B, N)
    value = np.take_along_axis(correspondence, best_column[:, :, None], axis=2)[:, :, 0]
    mutual = np.take_along_axis(best_row, best_column, axis=1) == np.arange(rows)[None, :]
    return np.where((value > threshold) & mutual, best_column, -1).astype(np.int64)


def _normalisation(
    settings: TpsRpmSettings, data_batch: FloatArray, owned: Sequence[TpsRpmTemplate]
) -> tuple[FloatArray, FloatArray]:
    """Centre (B, 2) and scale (B,) of each data set: its own (``separate``) or its template's."""
    batch, columns, _ = data_batch.shape
    if settings.normalisation == "separate" and columns > 0:
        centres = data_batch.mean(axis=1)
        spread = np.sqrt(np.mean(np.sum((data_batch - centres[:, None, :]) ** 2, axis=2), axis=1))
        scales = np.where(spread > 0, spread, settings.rms_radius) / settings.rms_radius
    else:
        centres = np.array([p.centre for p in owned], dtype=np.float64).reshape(batch, 2)
        scales = np.array([p.scale for p in owned], dtype=np.float64)
    return centres, scales


def _empty_batch(
    owned: Sequence[TpsRpmTemplate], owner: IntArray, count: int, columns: int
) -> TpsRpmBatch:
    """The outputs when there is nothing to match (no template point, data point or data set)."""
    batch = len(owned)
    return TpsRpmBatch(
        correspondence=np.zeros((batch, count, columns)),
        matched=np.full((batch, count), -1, dtype=np.int64),
        bending_energy=np.zeros(batch),
        warped_template=np.array([p.template for p in owned], dtype=np.float64).reshape(
            batch, count, 2
        ),
        nonaffine=np.zeros((batch, count, 3)),
        affine=np.repeat(np.eye(3)[None], batch, axis=0),
        data_centre=np.array([p.centre for p in owned], dtype=np.float64).reshape(batch, 2),
        data_scale=np.array([p.scale for p in owned], dtype=np.float64),
        owner=owner,
    )


def _anneal_all(
    templates: Sequence[TpsRpmTemplate], owner: IntArray, normalised: FloatArray
) -> tuple[FloatArray, FloatArray, list[FloatArray]]:
    """Final H (B, K, N), targets (B, K, 2) and each data set's temperature schedule: one batched
    annealing with the code's schedule, else one run per data set (the paper's schedule)."""
    settings = templates[0].settings
    batch, columns, _ = normalised.shape
    count = templates[0].template.shape[0]
    rng = None if settings.noise_seed is None else np.random.default_rng(settings.noise_seed)
    order = np.argsort(owner, kind="stable")
    final_h = np.zeros((batch, count, columns))
    final_targets = np.zeros((batch, count, 2))
    schedules: list[FloatArray] = []
    if settings.schedule == "code":
        temperatures = code_temperatures(settings)
        h, targets = anneal(templates, owner[order], normalised[order], temperatures, rng)
        final_h[order], final_targets[order] = h, targets
        schedules = [temperatures] * batch
    else:
        for index in range(batch):
            prepared = templates[int(owner[index])]
            temperatures = paper_temperatures(
                prepared.normalised, normalised[index], settings.anneal_rate
            )
            h, targets = anneal(
                [prepared],
                np.zeros(1, dtype=np.int64),
                normalised[index : index + 1],
                temperatures,
                rng,
            )
            final_h[index], final_targets[index] = h[0], targets[0]
            schedules.append(temperatures)
    return final_h, final_targets, schedules


def _final_warps(
    templates: Sequence[TpsRpmTemplate],
    owner: IntArray,
    schedules: list[FloatArray],
    final_targets: FloatArray,
    centres: FloatArray,
    scales: FloatArray,
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """The TPS fitted to the final targets at the last temperature: non-affine (B, K, 3) and
    affine (B, 3, 3) parameters, bending energy (B,) and the warped template (B, K, 2) in image
    coordinates."""
    settings = templates[0].settings
    batch, count, _ = final_targets.shape
    nonaffine = np.zeros((batch, count, 3))
    affine = np.zeros((batch, 3, 3))
    bending = np.zeros(batch)
    warped = np.zeros((batch, count, 2))
    targets_h = np.concatenate([np.ones((batch, count, 1)), final_targets], axis=2)
    for template_index, prepared in enumerate(templates):
        members = np.nonzero(owner == template_index)[0]
        if settings.schedule == "code" and members.size:
            groups = [members]
        else:
            groups = [members[i : i + 1] for i in range(members.size)]
        for group in groups:
            if group.size == 0:
                continue
            bending_op, affine_op, offset, _, _ = prepared.operators(schedules[int(group[0])])
            c = bending_op[-1] @ targets_h[group]  # (G, K, 3)
            d = offset[-1] + affine_op[-1] @ targets_h[group]  # (G, 3, 3)
            nonaffine[group], affine[group] = c, d
            warp = c[:, :, 1:3]
            bending[group] = np.maximum(
                np.einsum("gki,kj,gji->g", warp, prepared.basis.kernel, warp), 0.0
            )
            mapped = homogeneous(prepared.normalised)[None] @ d + prepared.basis.kernel[None] @ c
            warped[group] = centres[group, None, :] + scales[group, None, None] * mapped[:, :, 1:3]
    return nonaffine, affine, bending, warped


def tps_rpm_multi_batch(
    templates: Sequence[TpsRpmTemplate], owner: IntArray, data_batch: FloatArray
) -> TpsRpmBatch:
    """TPS-RPM of several templates (same K and settings) against B data sets of equal size.

    Args:
        templates: prepared templates.
        owner: (B,) index into ``templates`` for each data set.
        data_batch: (B, N, 2) data sets in image coordinates.

    Returns:
        The array outputs, in the order of ``data_batch``.
    """
    if len(templates) == 0:
        raise ValueError("at least one template is needed")
    settings = templates[0].settings
    count = templates[0].template.shape[0]
    if any(p.settings != settings or p.template.shape[0] != count for p in templates):
        raise ValueError("all templates must share the settings and the number of points")
    data_batch = np.asarray(data_batch, dtype=np.float64)
    if data_batch.ndim != 3 or data_batch.shape[2] != 2:
        raise ValueError(f"data_batch must have shape (B, N, 2), got {data_batch.shape}")
    owner = np.asarray(owner, dtype=np.int64).reshape(-1)
    batch, columns, _ = data_batch.shape
    if owner.shape[0] != batch:
        raise ValueError("owner must give one template index per data set")
    owned = [templates[int(i)] for i in owner]
    centres, scales = _normalisation(settings, data_batch, owned)
    if count == 0 or columns == 0 or batch == 0:
        return _empty_batch(owned, owner, count, columns)
    normalised = (data_batch - centres[:, None, :]) / scales[:, None, None]
    final_h, final_targets, schedules = _anneal_all(templates, owner, normalised)
    nonaffine, affine, bending, warped = _final_warps(
        templates, owner, schedules, final_targets, centres, scales
    )
    return TpsRpmBatch(
        correspondence=final_h,
        matched=batch_matches(final_h, settings.match_threshold),
        bending_energy=bending,
        warped_template=warped,
        nonaffine=nonaffine,
        affine=affine,
        data_centre=centres,
        data_scale=scales,
        owner=owner,
    )


def tps_rpm_batch(
    template: FloatArray | TpsRpmTemplate,
    data_batch: FloatArray,
    settings: TpsRpmSettings | None = None,
) -> list[TpsRpmResult]:
    """Run TPS-RPM of one template against B data sets of equal size in one vectorised loop.

    Args:
        template: (K, 2) image points, or a :class:`TpsRpmTemplate` prepared once (its settings
            are used and ``settings`` must be None or the same).
        data_batch: (B, N, 2) image points.
        settings: run settings (the defaults when None).

    Returns:
        B results, identical to B calls of :func:`tps_rpm` (up to float rounding); with
        ``noise_seed`` set the batch draws its noise from one generator.
    """
    if isinstance(template, TpsRpmTemplate):
        prepared = template
        if settings is not None and settings != prepared.settings:
            raise ValueError("settings differ from those the template was prepared with")
    else:
        prepared = TpsRpmTemplate(template, settings)
    data_batch = np.asarray(data_batch, dtype=np.float64)
    if data_batch.ndim != 3 or data_batch.shape[2] != 2:
        raise ValueError(f"data_batch must have shape (B, N, 2), got {data_batch.shape}")
    outputs = tps_rpm_multi_batch(
        [prepared], np.zeros(data_batch.shape[0], dtype=np.int64), data_batch
    )
    return [outputs.result(index, [prepared]) for index in range(data_batch.shape[0])]


def tps_rpm(
    template: FloatArray | TpsRpmTemplate,
    data: FloatArray,
    settings: TpsRpmSettings | None = None,
) -> TpsRpmResult:
    """Register a template (K, 2) onto data (N, 2), both in image coordinates.

    >>> square = np.array([[0.0, 0.0], [10, 0], [10, 10], [0, 10], [5, 2]])
    >>> result = tps_rpm(square, square * 2 + 7)
    >>> result.matches[:, 1].tolist(), round(result.bending_energy, 6)
    ([0, 1, 2, 3, 4], 0.0)
    """
    data = np.asarray(data, dtype=np.float64).reshape(-1, 2)
    return tps_rpm_batch(template, data[None], settings)[0]


def match_points(
    template: FloatArray, data: FloatArray, settings: TpsRpmSettings | None = None
) -> tuple[IntArray, FloatArray, TpsRpmResult | None]:
    """One-to-one association of template points with data points through TPS-RPM.

    Used where TPS-RPM replaces a distance-based assignment (the Kalman3 baseline and the plain
    ``tps-rpm`` gap matcher): matched template points take their data point, unmatched ones
    their TPS-mapped position.

    Args:
        template: ``(K, 2)`` points (predictions).
        data: ``(N, 2)`` points (detections).
        settings: TPS-RPM settings.

    Returns:
        ``(K,)`` data row per template point (-1 when unmatched), ``(K, 2)`` positions, and the
        TPS-RPM result (None when either set is empty).

    >>> rows, positions, _ = match_points(np.array([[0.0, 0], [9, 0], [9, 9], [0, 9]]),
    ...                                   np.array([[1.0, 1], [0, 10], [10, 10], [10, 1]]))
    >>> rows.tolist()
    [0, 3, 2, 1]
    """
    template = np.asarray(template, dtype=np.float64).reshape(-1, 2)
    data = np.asarray(data, dtype=np.float64).reshape(-1, 2)
    rows = np.full(len(template), -1, dtype=np.int64)
    if len(template) == 0 or len(data) == 0:
        return rows, template.copy(), None
    result = tps_rpm(template, data, settings)
    positions = result.transform(template)
    if len(result.matches):
        rows[result.matches[:, 0]] = result.matches[:, 1]
        positions[result.matches[:, 0]] = data[result.matches[:, 1]]
    return rows, positions, result
