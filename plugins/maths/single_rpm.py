"""TPS-RPM of one small point set onto another, with two-dimensional arrays.

:func:`trackfw_plugins.maths.tps_rpm.tps_rpm` runs one data set through the batched annealing
(arrays ``(K, N, B)`` with ``B = 1``), whose hundreds of numpy calls per temperature level cost
far more than the arithmetic when K and N are a handful of points, as in the GTCSA-like tracker's
per-frame group fits. :func:`tps_rpm_single` runs the same algorithm (same steps, same stopping
rules, same final fit) on ``(K, N)`` arrays with fewer and cheaper calls; it agrees with
:func:`tps_rpm` up to float rounding (summation order), see
``tests/plugins/maths/test_single_rpm.py``. Settings it does not cover (the paper's schedule,
the mixture mode, noise, template normalisation, early stop, float32) go to :func:`tps_rpm`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from functools import lru_cache

import numpy as np

from trackfw.arrays import FloatArray, IntArray
from trackfw_plugins.maths.thin_plate import homogeneous
from trackfw_plugins.maths.tps_rpm import TpsRpmResult, threshold_matches, tps_rpm
from trackfw_plugins.maths.tps_rpm_template import (
    TpsRpmSettings,
    TpsRpmTemplate,
    code_temperatures,
)

# The batched loop's constants: the floor under which a row of H is not used to move its
# virtual target, and the cap on d²/T that keeps exp() out of subnormal numbers.
_ROW_SUM_FLOOR = 1e-12
_EXPONENT_CAP = 700.0


@lru_cache(maxsize=16)
def _temperatures(settings: TpsRpmSettings) -> FloatArray:
    # The same schedule for every fit with these settings.
    temperatures = code_temperatures(settings)
    temperatures.setflags(write=False)
    return temperatures


def covers(settings: TpsRpmSettings) -> bool:
    """Whether :func:`tps_rpm_single` implements these settings (else it calls tps_rpm)."""
    return (
        settings.mode == "rpm"
        and settings.schedule == "code"
        and settings.noise_seed is None
        and settings.normalisation == "separate"
        and not settings.early_stop
        and settings.precision == "float64"
    )


class _Workspace:
    """Buffers of one annealing of G problems laid block-diagonally (``K = sum K_g`` rows).

    ``bordered`` is ``[[E, row slack], [column slack, 0]]`` ``(K+1, N+1)``, E zero outside the
    blocks. Row ``s`` of ``scalings`` is ``[b_s, 1, a_s, 1]``, the scalings after sweep ``s``
    with a 1 after each, so that one matrix-vector product with ``bordered`` gives a sweep's row
    (or column) sums with their slack; row ``s`` of ``sums`` holds that sweep's sums in the same
    layout (the 1s in the gaps make those entries drop out of the stopping test). Each problem's
    stopping sweep is found after the sweeps, in one pass, instead of by a test after each.

    Args:
        rows: ``(G,)`` template points per problem.
        columns: ``(G,)`` data points per problem.
        outlier_mass: ``(G,)`` each problem's m_out.
        settings: the sweeps and the tolerance.
    """

    def __init__(
        self, rows: IntArray, columns: IntArray, outlier_mass: FloatArray, settings: TpsRpmSettings
    ) -> None:
        count, width, sweeps = int(rows.sum()), int(columns.sum()), settings.sinkhorn_maxit
        row_group = np.repeat(np.arange(len(rows)), rows)
        column_group = np.repeat(np.arange(len(columns)), columns)
        self.bordered = np.zeros((count + 1, width + 1))
        self.bordered[count, :width] = outlier_mass[column_group]
        self.affinity = self.bordered[:count, :width]
        # Zero outside the blocks (None for one problem): a product then sums its block only.
        self.mask = None if len(rows) == 1 else row_group[:, None] == column_group[None, :]
        self.row_slack = self.bordered[:count, width]
        self.row_mass = outlier_mass[row_group]
        self.scalings = np.ones((sweeps + 1, width + count + 2))
        self.sums = np.ones((sweeps, width + count + 2))
        self.count, self.width, self.sweeps = count, width, sweeps
        first_row = width + 1
        with_row_slack, with_column_slack = self.bordered[:count], self.bordered[:, :width]
        # One sweep is four calls on these views (see ``sinkhorn``).
        self.sweep_calls = [
            (
                with_row_slack,
                self.scalings[sweep, :first_row],
                self.sums[sweep, first_row:-1],
                self.scalings[sweep + 1, first_row:-1],
                self.scalings[sweep + 1, first_row:],
                with_column_slack,
                self.sums[sweep, :width],
                self.scalings[sweep + 1, :width],
            )
            for sweep in range(sweeps)
        ]
        self.initial_row = self.scalings[0, first_row:-1]
        # The stopping test per problem: its squared errors summed by one product.
        self.limits = settings.sinkhorn_tol**2 * (rows + columns).astype(np.float64)
        self.limit_one = float(self.limits[0])
        owner = np.zeros(width + count + 2, dtype=np.int64)
        owner[:width], owner[first_row:-1] = column_group, row_group
        self.indicator = (owner[:, None] == np.arange(len(rows))[None, :]).astype(np.float64)
        self.row_index = (row_group, first_row + np.arange(count))
        self.results = [
            (self.scalings[sweep, first_row:-1], self.scalings[sweep, :width])
            for sweep in range(sweeps + 1)
        ]
        self.column_index = (column_group, np.arange(width))

    def sinkhorn(self, root: float, inverse_root: float) -> tuple[FloatArray, FloatArray]:
        """:func:`trackfw_plugins.maths.sinkhorn.sinkhorn` on ``affinity`` ``(K, N)`` at T.

        The batched code's row update ``a <- a / (a (E b + slack))`` is ``1 / (E b + slack)``
        (and likewise for the columns), so a sweep is two products and two reciprocals.

        Args:
            root: T^1/2 (the row slack is m_out T^1/2).
            inverse_root: T^-1/2, the first row scaling (see the batched sinkhorn).

        Returns:
            Row scaling ``(K,)`` and column scaling ``(N,)``: H = a_p E_pq b_q.
        """
        np.multiply(self.row_mass, root, out=self.row_slack)
        self.initial_row[:] = inverse_root
        for (
            matrix,
            scaling,
            sums,
            new_scaling,
            row_scaling,
            t_matrix,
            t_sums,
            t_new,
        ) in self.sweep_calls:
            np.reciprocal(np.dot(matrix, scaling, out=sums), out=new_scaling)
            np.reciprocal(np.dot(row_scaling, t_matrix, out=t_sums), out=t_new)
        # The authors' test for every sweep at once: the mean squared error against 1 of the
        # sums scaled by the scalings they were computed with; a problem's result is the
        # scalings of the first sweep that meets it, else of the last sweep.
        error = self.scalings[:-1] * self.sums
        error -= 1.0
        error *= error
        if self.mask is None:
            # One problem: its first sweep that meets the test, read from a stored view.
            met_one = np.flatnonzero(error.sum(axis=1) < self.limit_one)
            return self.results[int(met_one[0]) + 1 if len(met_one) else self.sweeps]
        met = error.dot(self.indicator) < self.limits  # (sweeps, G)
        stop = np.where(met.any(axis=0), met.argmax(axis=0) + 1, self.sweeps)
        row_group, row_position = self.row_index
        column_group, column_position = self.column_index
        return (
            self.scalings[stop[row_group], row_position],
            self.scalings[stop[column_group], column_position],
        )


def _block_operators(
    prepared: list[TpsRpmTemplate], temperatures: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """Each level's warp operators of the G templates as one block-diagonal ``(L, K, K)`` and
    the stacked offsets ``(L, K, 2)``: the warped templates are ``offset + warp @ targets``."""
    operators = [template.operators(temperatures) for template in prepared]
    if len(operators) == 1:
        return operators[0][3], operators[0][4]
    count = sum(len(template.normalised) for template in prepared)
    warp = np.zeros((len(temperatures), count, count))
    first = 0
    for template, (_, _, _, block, _) in zip(prepared, operators, strict=True):
        last = first + len(template.normalised)
        warp[:, first:last, first:last] = block
        first = last
    return warp, np.concatenate([ops[4] for ops in operators], axis=1)


def _anneal(
    prepared: list[TpsRpmTemplate], data: list[FloatArray], temperatures: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """The annealing loop of G problems on normalised ``(N_g, 2)`` data, block-diagonally.

    Returns:
        H ``(K, N)`` (zero outside the blocks) and the virtual targets ``(K, 2)``.
    """
    settings = prepared[0].settings
    warp, warp_offset = _block_operators(prepared, temperatures)
    work = _Workspace(
        np.array([len(template.normalised) for template in prepared]),
        np.array([len(points) for points in data]),
        np.array([template.outlier_mass for template in prepared]),
        settings,
    )
    affinity, mask = work.affinity, work.mask
    warped = np.concatenate([template.normalised for template in prepared])  # (K, 2)
    stacked = np.concatenate(data)  # (N, 2)
    # [1, x, y] per data point: one product gives the row sums of H and its weighted points.
    data_h = np.concatenate([np.ones((len(stacked), 1)), stacked], axis=1)
    other = np.empty(affinity.shape)
    targets = warped
    row_scale = column_scale = np.ones(0)
    for level, temperature in enumerate(temperatures.tolist()):
        root = math.sqrt(temperature)
        inverse_root = 1.0 / root
        scaled_x = stacked[None, :, 0] * inverse_root
        scaled_y = stacked[None, :, 1] * inverse_root
        for _ in range(settings.perT_maxit):
            moved = warped * inverse_root
            # E = exp(-min(d²/T, cap)): the cap keeps exp() out of slow subnormal numbers.
            np.subtract(scaled_x, moved[:, 0:1], out=affinity)
            np.multiply(affinity, affinity, out=affinity)
            np.subtract(scaled_y, moved[:, 1:2], out=other)
            np.multiply(other, other, out=other)
            affinity += other
            np.minimum(affinity, _EXPONENT_CAP, out=affinity)
            np.negative(affinity, out=affinity)
            np.exp(affinity, out=affinity)
            if mask is not None:
                affinity *= mask
            row_scale, column_scale = work.sinkhorn(root, inverse_root)
            # Virtual targets y_p = sum_q h_pq w_q / sum_q h_pq; the row scaling cancels.
            sums = affinity.dot(column_scale[:, None] * data_h)
            usable = row_scale * sums[:, 0] >= _ROW_SUM_FLOOR
            if usable.all():
                targets = sums[:, 1:3] / sums[:, 0:1]
            else:
                safe_sum = np.where(usable, sums[:, 0], 1.0)[:, None]
                targets = np.where(usable[:, None], sums[:, 1:3] / safe_sum, warped)
            warped = warp_offset[level] + warp[level].dot(targets)
    correspondence = row_scale[:, None] * affinity * column_scale[None, :]
    return correspondence, targets


def _result(
    prepared: TpsRpmTemplate,
    correspondence: FloatArray,
    targets: FloatArray,
    centre: FloatArray,
    scale: float,
) -> TpsRpmResult:
    """The final fit of one problem (at the last temperature) and its outputs."""
    settings = prepared.settings
    bending, affine, offset = prepared.operators(_temperatures(settings))[0:3]
    targets_h = np.concatenate([np.ones((len(targets), 1)), targets], axis=1)
    nonaffine = bending[-1] @ targets_h
    affine_part = offset[-1] + affine[-1] @ targets_h
    warp = nonaffine[:, 1:3]
    kernel = prepared.basis.kernel
    mapped = (homogeneous(prepared.normalised) @ affine_part + kernel @ nonaffine)[:, 1:3]
    return TpsRpmResult(
        correspondence=correspondence,
        matches=threshold_matches(correspondence, settings.match_threshold),
        bending_energy=float(max(np.einsum("ki,kj,ji->", warp, kernel, warp), 0.0)),
        warped_template=centre + scale * mapped,
        nonaffine=nonaffine,
        affine=affine_part,
        template_centre=prepared.centre,
        template_scale=prepared.scale,
        data_centre=centre,
        data_scale=scale,
        normalised_template=prepared.normalised,
    )


def tps_rpm_groups(
    problems: Sequence[tuple[FloatArray, FloatArray]], settings: TpsRpmSettings | None = None
) -> list[TpsRpmResult]:
    """Register G small templates ``(K_g, 2)`` onto their data ``(N_g, 2)`` (image coordinates).

    The G problems are independent and may differ in size; they anneal together, laid
    block-diagonally, so G of them cost about as many numpy calls as one. Each result is that
    of :func:`tps_rpm` on its problem up to float rounding.

    >>> square = np.array([[0.0, 0.0], [10, 0], [10, 10], [0, 10], [5, 2]])
    >>> first, second = tps_rpm_groups([(square, square * 2 + 7), (square[:4], square[:4] + 1)])
    >>> first.matches[:, 1].tolist(), second.matches[:, 1].tolist()
    ([0, 1, 2, 3, 4], [0, 1, 2, 3])
    """
    settings = settings if settings is not None else TpsRpmSettings()
    arrays = [
        (
            np.asarray(template, dtype=np.float64).reshape(-1, 2),
            np.asarray(data, dtype=np.float64).reshape(-1, 2),
        )
        for template, data in problems
    ]
    annealed = [
        index
        for index, (template, data) in enumerate(arrays)
        if covers(settings) and len(template) and len(data)
    ]
    results = [
        tps_rpm(template, data, settings) if index not in annealed else None
        for index, (template, data) in enumerate(arrays)
    ]
    if not annealed:
        return results  # type: ignore[return-value]
    prepared = [TpsRpmTemplate(arrays[index][0], settings) for index in annealed]
    normalised, centres, scales = [], [], []
    for index in annealed:
        data = arrays[index][1]
        centre = data.mean(axis=0)
        spread = math.sqrt(float(np.mean(np.sum((data - centre) ** 2, axis=1))))
        scale = (spread if spread > 0 else settings.rms_radius) / settings.rms_radius
        normalised.append((data - centre) / scale)
        centres.append(centre)
        scales.append(scale)
    correspondence, targets = _anneal(prepared, normalised, _temperatures(settings))
    row, column = 0, 0
    for slot, index in enumerate(annealed):
        rows, columns = len(arrays[index][0]), len(arrays[index][1])
        results[index] = _result(
            prepared[slot],
            correspondence[row : row + rows, column : column + columns],
            targets[row : row + rows],
            centres[slot],
            scales[slot],
        )
        row, column = row + rows, column + columns
    return results  # type: ignore[return-value]


def tps_rpm_single(
    template: FloatArray, data: FloatArray, settings: TpsRpmSettings | None = None
) -> TpsRpmResult:
    """Register a small template ``(K, 2)`` onto data ``(N, 2)``, both in image coordinates.

    The result is that of :func:`tps_rpm` up to float rounding.

    >>> square = np.array([[0.0, 0.0], [10, 0], [10, 10], [0, 10], [5, 2]])
    >>> result = tps_rpm_single(square, square * 2 + 7)
    >>> result.matches[:, 1].tolist(), round(result.bending_energy, 6)
    ([0, 1, 2, 3, 4], 0.0)
    """
    return tps_rpm_groups([(template, data)], settings)[0]
