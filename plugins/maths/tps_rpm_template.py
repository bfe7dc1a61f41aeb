"""TPS-RPM inputs: settings, normalisation, temperature schedules and the prepared template.

See docs/algorithms/tps-rpm.md#coordinate-normalisation. Template and data are normalised
separately to unit RMS radius
so that the authors' absolute temperature schedule applies to pixel coordinates. A template is
prepared once (:class:`TpsRpmTemplate`): its normalisation, Φ, QR factors and the per-temperature
fit operators are cached, so that the many windows matched against it share them. The annealing
itself is :mod:`trackfw_plugins.maths.tps_rpm`.
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from pydantic import ConfigDict, Field

from trackfw.arrays import FloatArray
from trackfw.stages import FiniteModel
from trackfw_plugins.maths.thin_plate import TpsBasis, homogeneous


class TpsRpmSettings(FiniteModel):
    """TPS-RPM parameters; defaults are the authors' code values and ours.

    See docs/algorithms/tps-rpm.md#parameters.
    """

    model_config = ConfigDict(frozen=True, extra="forbid")

    T_init: float = Field(0.5, gt=0, description="Initial temperature (cMIX demo call).")
    T_finalfac: float = Field(500.0, gt=1, description="T_final = T_init / T_finalfac.")
    anneal_rate: float = Field(0.93, gt=0, lt=1, description="T <- anneal_rate * T per level.")
    perT_maxit: int = Field(  # noqa: N815 - the documented YAML key
        5, ge=1, description="Alternating updates per temperature level."
    )
    lamda1_init: float = Field(
        1.0, gt=0, description="Bending regulariser: lambda1 = lamda1_init * K * T."
    )
    lamda2_init: float = Field(
        0.01, gt=0, description="Affine regulariser: lambda2 = lamda2_init * K * T."
    )
    sinkhorn_maxit: int = Field(10, ge=1, description="Maximum Sinkhorn sweeps per softassign.")
    sinkhorn_tol: float = Field(
        0.05, gt=0, description="Stop Sinkhorn when the mean squared row/column-sum error < tol^2."
    )
    mode: Literal["rpm", "mixture"] = Field(
        "rpm",
        description="'rpm': two-way normalisation with outlier row and column (code 'mix-rpm'); "
        "'mixture': one-way normalisation over data columns (code default).",
    )
    schedule: Literal["code", "paper"] = Field(
        "code",
        description="'code': T_init / T_finalfac absolute schedule; 'paper': CVIU data-driven "
        "schedule (largest squared pair distance down to mean squared NN distance).",
    )
    noise_seed: int | None = Field(
        None, description="Seed of the code's symmetry-breaking noise; None switches it off."
    )
    rms_radius: float = Field(1.0, gt=0, description="RMS radius of the normalised point sets.")
    normalisation: Literal["separate", "template"] = Field(
        "separate",
        description="'separate': template and data each normalised; 'template': one "
        "similarity from the template applied to both (Kalman3).",
    )
    match_threshold: float = Field(
        0.5, ge=0, lt=1, description="A pair matches when h > threshold and is row/column max."
    )
    early_stop: bool = Field(
        False,
        description="Stop a data set when max|dH| between the ends of two consecutive levels "
        "< early_stop_tol; the final fit then uses the last level's regularisers.",
    )
    early_stop_tol: float = Field(1e-4, gt=0, description="Tolerance of early_stop.")
    precision: Literal["float64", "float32"] = Field(
        "float64",
        description="Float type of the annealing loop; float32 is about twice as fast and "
        "agrees with float64 to ~1e-5 in H (the final fit is always float64).",
    )


def one_image_settings() -> TpsRpmSettings:
    """TPS-RPM settings for two point sets that lie in one image frame (Kalman3's association,
    the plain TPS-RPM gap matcher).

    Both sets live in one image frame, so one similarity computed from the template is applied to
    both (docs/algorithms/tps-rpm.md#coordinate-normalisation); float32 halves the time with the
    same matches.
    """
    return TpsRpmSettings(normalisation="template", precision="float32")


def normalise_points(
    points: FloatArray, rms_radius: float = 1.0
) -> tuple[FloatArray, FloatArray, float]:
    """Centre a point set and scale it to the given RMS radius.

    Args:
        points: (P, 2) points.
        rms_radius: RMS distance of the normalised points from the origin.

    Returns:
        ``(normalised (P, 2), centre (2,), scale)`` with ``points = centre + scale * normalised``.
        A set with zero spread gets scale 1 / rms_radius times 1.

    >>> normalised, centre, scale = normalise_points(np.array([[0.0, 0.0], [4.0, 0.0]]))
    >>> normalised.tolist(), centre.tolist(), scale
    ([[-1.0, 0.0], [1.0, 0.0]], [2.0, 0.0], 2.0)
    """
    points = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    if points.shape[0] == 0:
        return points.copy(), np.zeros(2), 1.0
    centre = points.mean(axis=0)
    spread = float(np.sqrt(np.mean(np.sum((points - centre) ** 2, axis=1))))
    if spread <= 0.0:
        spread = rms_radius
    scale = spread / rms_radius
    return (points - centre) / scale, centre, scale


def code_temperatures(settings: TpsRpmSettings) -> FloatArray:
    """Temperatures of the code schedule, T_init·r^j while the level is reached (86 by default).

    >>> len(code_temperatures(TpsRpmSettings()))
    86
    """
    return _schedule(settings.T_init, settings.T_init / settings.T_finalfac, settings.anneal_rate)


def _schedule(initial: float, final: float, rate: float) -> FloatArray:
    # Repeated multiplication, as cMIX does, so the number of levels matches the code exactly.
    temperatures = []
    temperature = initial
    while True:
        temperatures.append(temperature)
        temperature *= rate
        if temperature < final:
            break
    return np.asarray(temperatures)


def paper_temperatures(template: FloatArray, data: FloatArray, rate: float) -> FloatArray:
    """CVIU rule: T from the largest squared pair distance to the template's mean squared NN."""
    cross = np.sum((template[:, None, :] - data[None, :, :]) ** 2, axis=2)
    within = np.sum((template[:, None, :] - template[None, :, :]) ** 2, axis=2)
    np.fill_diagonal(within, np.inf)
    nearest = within.min(axis=1)
    finite = nearest[np.isfinite(nearest)]
    initial = float(cross.max())
    final = float(np.mean(finite)) if finite.size else 1.0
    if initial <= final:
        initial = final / rate
    return _schedule(initial, final, rate)


class TpsRpmTemplate:
    """A template prepared once for many TPS-RPM runs: normalisation, Φ, QR, fit operators.

    Args:
        template: (K, 2) template points in image coordinates.
        settings: the run settings.
    """

    def __init__(self, template: FloatArray, settings: TpsRpmSettings | None = None) -> None:
        self.settings = settings if settings is not None else TpsRpmSettings()
        self.template = np.asarray(template, dtype=np.float64).reshape(-1, 2)
        self.normalised, self.centre, self.scale = normalise_points(
            self.template, self.settings.rms_radius
        )
        self.basis = TpsBasis.from_template(self.normalised)
        count = max(self.template.shape[0], 1)
        # Outlier slack m_out = e^-1 / sqrt(T0), T0 = largest squared radius (our centred T0).
        squared_radius = float(np.max(np.sum(self.normalised**2, axis=1), initial=0.0))
        self.outlier_mass = float(
            np.exp(-1.0) / np.sqrt(squared_radius if squared_radius > 0 else 1.0)
        )
        self._operators: dict[tuple[float, ...], tuple[FloatArray, ...]] = {}
        self._count = count

    def operators(self, temperatures: FloatArray) -> tuple[FloatArray, ...]:
        """Per-level fit operators for these temperatures (cached).

        Returns:
            ``bending (L,K,K)``, ``affine (L,3,K)``, ``offset (L,3,3)``, ``warp (L,K,K)``
            and ``warp_offset (L,K,2)``: the warped template is ``warp_offset + warp @ y``.
        """
        key = tuple(float(value) for value in temperatures)
        cached = self._operators.get(key)
        if cached is not None:
            return cached
        temperatures = np.asarray(temperatures, dtype=np.float64)
        factor = self._count * temperatures
        bending, affine, offset = self.basis.linear_operators(
            self.settings.lamda1_init * factor, self.settings.lamda2_init * factor
        )
        template_h = homogeneous(self.normalised)
        # X = [1,U] d + Φ c with c = C Y and d = G0 + D Y, so X = [1,U] G0 + ([1,U] D + Φ C) Y.
        # Column j of X depends on column j of Y only, so x, y coordinates need a (K, K) operator
        # on the virtual targets and a constant offset; Y's column of ones feeds column 0 only.
        warp = template_h[None] @ affine + self.basis.kernel[None] @ bending
        warp_offset = (template_h[None] @ offset)[:, :, 1:3]
        result = (bending, affine, offset, warp, warp_offset)
        self._operators[key] = result
        return result
