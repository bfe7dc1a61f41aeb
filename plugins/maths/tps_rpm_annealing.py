"""The TPS-RPM annealing loop (docs/algorithms/tps-rpm.md#speed).

:func:`anneal` runs B normalised data sets of equal size against their prepared templates in
one vectorised loop. Internally the batch is the *last* axis (arrays (K, N, B)), so that sums
over K or N are contiguous. Because the regularised fit is linear in the virtual targets, one
TPS update is a single (K, K) @ (K, 2B) product per template. Sinkhorn is run on scaling vectors
(H = diag(a) E diag(b)); every data set stops its own Sinkhorn iteration by the code's rule, so
batched and one-at-a-time runs agree.

Speed (one core, ~1000 data sets of 8-9 points): the loop is a few hundred numpy calls per
temperature level, so the (K, N, B) and (K, B) arrays are preallocated and written with
``out=``; every array keeps the batch axis innermost and contiguous (einsum over a boolean-index
copy, whose batch axis ends up outermost, is several times slower); full-size ufuncs get no
scalar or (B,)-vector operands (numpy's broadcast paths for those are slow); and H itself is
formed only once, after the last level.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from trackfw.arrays import FloatArray, IntArray
from trackfw_plugins.maths.sinkhorn import SinkhornWorkspace, sinkhorn
from trackfw_plugins.maths.tps_rpm_template import TpsRpmTemplate

#: A target whose row mass Σ h falls below this keeps its warped position.
ROW_SUM_FLOOR = 1e-12


def anneal(
    templates: Sequence[TpsRpmTemplate],
    owner: IntArray,
    data: FloatArray,
    temperatures: FloatArray,
    rng: np.random.Generator | None,
) -> tuple[FloatArray, FloatArray]:
    """The annealing loop on normalised data.

    Args:
        templates: prepared templates, all with the same K and settings.
        owner: (B,) non-decreasing index of each data set's template.
        data: (B, N, 2) normalised data sets.
        temperatures: (L,) schedule.
        rng: generator of the symmetry-breaking noise, or None.

    Returns:
        Final H (B, K, N) and final virtual targets y (B, K, 2), normalised coordinates.
    """
    return _Annealing(templates, owner, data, temperatures, rng).run(temperatures)


class _Annealing:
    """One annealing run: the data sets still annealing, their (K, N, B) work arrays, the results.

    Every array keeps the batch axis last and contiguous (see the module notes on speed); the
    work arrays shrink only when early_stop retires data sets.
    """

    def __init__(
        self,
        templates: Sequence[TpsRpmTemplate],
        owner: IntArray,
        data: FloatArray,
        temperatures: FloatArray,
        rng: np.random.Generator | None,
    ) -> None:
        self.settings = settings = templates[0].settings
        self.count = count = templates[0].normalised.shape[0]
        batch, self.columns, _ = data.shape
        self.dtype = dtype = np.float32 if settings.precision == "float32" else np.float64
        self.n_templates = len(templates)
        self.rng = rng
        self.operators = [
            tuple(array.astype(dtype) for array in prepared.operators(temperatures))
            for prepared in templates
        ]
        stacked_template = np.stack([prepared.normalised for prepared in templates])[owner]
        stacked_template = stacked_template.astype(dtype)
        outlier_mass = np.array([prepared.outlier_mass for prepared in templates])[owner]
        self.outlier_mass: FloatArray = outlier_mass.astype(dtype)
        data = data.astype(dtype)
        self.final_h = np.zeros((batch, count, self.columns))
        self.final_targets = np.zeros((batch, count, 2))
        self.alive = np.arange(batch)
        self.alive_owner = owner
        self.data_x = np.ascontiguousarray(data[:, :, 0].T)  # (N, B)
        self.data_y = np.ascontiguousarray(data[:, :, 1].T)
        self.warped_x = np.ascontiguousarray(stacked_template[:, :, 0].T)  # (K, B)
        self.warped_y = np.ascontiguousarray(stacked_template[:, :, 1].T)
        self.previous_h: FloatArray | None = None
        self.targets_x, self.targets_y = self.warped_x, self.warped_y
        self.noise_scale = 0.001 / count
        # The (K, N, B) arrays are reused across iterations (they shrink only with early_stop).
        self._allocate(batch)
        # A full array rather than a scalar: numpy's minimum with a scalar operand is not
        # vectorised and costs several passes.
        self.cap = np.full_like(self.affinity, 80.0 if dtype == np.float32 else 700.0)
        self.row_scale = np.ones((count, batch), dtype=dtype)
        self.column_scale = np.ones((self.columns, batch), dtype=dtype)

    def _allocate(self, batch: int) -> None:
        self.affinity = np.empty((self.count, self.columns, batch), dtype=self.dtype)
        self.other = np.empty_like(self.affinity)
        self.workspace = SinkhornWorkspace(
            self.count, self.columns, batch, self.settings.sinkhorn_maxit, self.dtype
        )

    def run(self, temperatures: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Anneal through ``temperatures``; returns the final H (B, K, N) and targets (B, K, 2)."""
        last_level = len(temperatures) - 1
        for level, temperature_value in enumerate(temperatures):
            self._level(level, float(temperature_value))
            if not self.settings.early_stop:
                # H itself is only needed at the end (the loop carries the scalings).
                continue
            h = self.row_scale[:, None, :] * self.affinity * self.column_scale[None, :, :]
            if level < last_level:
                if self.previous_h is not None:
                    h, all_done = self._retire_converged(h, self.previous_h)
                    if all_done:
                        return self.final_h, self.final_targets
                self.previous_h = h
        final_h = self.row_scale[:, None, :] * self.affinity * self.column_scale[None, :, :]
        self.final_h[self.alive] = np.moveaxis(final_h, 2, 0)
        self.final_targets[self.alive, :, 0] = self.targets_x.T
        self.final_targets[self.alive, :, 1] = self.targets_y.T
        return self.final_h, self.final_targets

    def _level(self, level: int, temperature: float) -> None:
        """The ``perT_maxit`` softassign and TPS updates at one temperature."""
        inverse_root = 1.0 / math.sqrt(temperature)
        # E = exp(-d²/T) is the code's m without its T^-1/2 factor; the row scaling absorbs it.
        row_slack = self.outlier_mass * math.sqrt(temperature)
        scaled_x = self.data_x * inverse_root
        scaled_y = self.data_y * inverse_root
        # Data sets are sorted by template, so each template owns one contiguous slice.
        bounds = np.searchsorted(self.alive_owner, np.arange(self.n_templates + 1))
        for _ in range(self.settings.perT_maxit):
            self._fill_affinity(scaled_x, scaled_y, inverse_root, temperature)
            self._scale(row_slack, inverse_root)
            self._move_targets()
            self._warp(level, bounds)

    def _fill_affinity(
        self, scaled_x: FloatArray, scaled_y: FloatArray, inverse_root: float, temperature: float
    ) -> None:
        """E = exp(-min(d²/T, cap)) (plus the symmetry-breaking noise) into ``affinity``."""
        affinity, other = self.affinity, self.other
        # (data - warped)² equals (warped - data)² exactly; numpy broadcasts faster when
        # the operand that varies along N comes first.
        np.subtract(scaled_x[None, :, :], (self.warped_x * inverse_root)[:, None, :], out=affinity)
        np.multiply(affinity, affinity, out=affinity)
        np.subtract(scaled_y[None, :, :], (self.warped_y * inverse_root)[:, None, :], out=other)
        np.multiply(other, other, out=other)
        affinity += other
        # Capping d²/T keeps exp() out of subnormal numbers, which are very slow on x86;
        # exp(-cap) is far below anything that can change H.
        np.minimum(affinity, self.cap[:, :, : affinity.shape[2]], out=affinity)
        np.negative(affinity, out=affinity)
        np.exp(affinity, out=affinity)
        if self.rng is not None:
            affinity += (
                self.rng.standard_normal(affinity.shape) * (self.noise_scale * np.sqrt(temperature))
            ).astype(self.dtype)

    def _scale(self, row_slack: FloatArray, inverse_root: float) -> None:
        """The row and column scalings of H = diag(row) E diag(column) (Sinkhorn for RPM)."""
        settings = self.settings
        if settings.mode == "rpm":
            self.row_scale, self.column_scale = sinkhorn(
                self.affinity,
                row_slack,
                self.outlier_mass,
                settings.sinkhorn_maxit,
                settings.sinkhorn_tol,
                inverse_root,
                self.workspace,
            )
        else:
            self.row_scale = np.ones((self.count, self.affinity.shape[2]), dtype=self.dtype)
            self.column_scale = 1.0 / (self.affinity.sum(axis=0) + row_slack)

    def _move_targets(self) -> None:
        """Virtual targets y_p = Σ_q h_pq w_q / Σ_q h_pq; the row scaling cancels."""
        affinity, column_scale = self.affinity, self.column_scale
        weight_sum = np.einsum("knb,nb->kb", affinity, column_scale)
        weighted_x = np.einsum("knb,nb->kb", affinity, column_scale * self.data_x)
        weighted_y = np.einsum("knb,nb->kb", affinity, column_scale * self.data_y)
        usable = self.row_scale * weight_sum >= ROW_SUM_FLOOR
        if usable.all():
            self.targets_x = np.divide(weighted_x, weight_sum, out=weighted_x)
            self.targets_y = np.divide(weighted_y, weight_sum, out=weighted_y)
        else:
            safe_sum = np.where(usable, weight_sum, 1.0)
            self.targets_x = np.where(usable, weighted_x / safe_sum, self.warped_x)
            self.targets_y = np.where(usable, weighted_y / safe_sum, self.warped_y)

    def _warp(self, level: int, bounds: IntArray) -> None:
        """Refit each template's TPS to its targets: one (K, K) @ (K, 2B) product per template."""
        targets_x, targets_y = self.targets_x, self.targets_y
        warped_x = np.empty_like(targets_x)
        warped_y = np.empty_like(targets_y)
        for index, (_, _, _, warp, warp_offset) in enumerate(self.operators):
            first, last = bounds[index], bounds[index + 1]
            if first == last:
                continue
            width = last - first
            moved = warp[level] @ np.concatenate(
                [targets_x[:, first:last], targets_y[:, first:last]], axis=1
            )
            np.add(warp_offset[level][:, 0:1], moved[:, :width], out=warped_x[:, first:last])
            np.add(warp_offset[level][:, 1:2], moved[:, width:], out=warped_y[:, first:last])
        self.warped_x, self.warped_y = warped_x, warped_y

    def _retire_converged(self, h: FloatArray, previous_h: FloatArray) -> tuple[FloatArray, bool]:
        """Store the results of the data sets whose H moved less than ``early_stop_tol`` and drop
        them from the work arrays; returns H of the others and whether none is left."""
        change = np.abs(h - previous_h).max(axis=(0, 1))
        finished = change < self.settings.early_stop_tol
        if not finished.any():
            return h, False
        done = self.alive[finished]
        self.final_h[done] = np.moveaxis(h[:, :, finished], 2, 0)
        self.final_targets[done, :, 0] = self.targets_x[:, finished].T
        self.final_targets[done, :, 1] = self.targets_y[:, finished].T
        keep = np.flatnonzero(~finished)
        self.alive, self.alive_owner = self.alive[keep], self.alive_owner[keep]
        if self.alive.size == 0:
            return h, True
        # take() keeps the batch axis innermost and contiguous (a boolean index
        # on the last axis would not, which slows every later einsum).
        h = np.take(h, keep, axis=2)
        self.data_x = np.take(self.data_x, keep, axis=1)
        self.data_y = np.take(self.data_y, keep, axis=1)
        self.warped_x = np.take(self.warped_x, keep, axis=1)
        self.warped_y = np.take(self.warped_y, keep, axis=1)
        self.outlier_mass = self.outlier_mass[keep]
        self._allocate(self.alive.size)
        return h, False
