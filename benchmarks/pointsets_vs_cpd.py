"""trackfw's TPS-RPM against pycpd's deformable CPD on the Chui–Rangarajan synthetic sets.

For the fish (98 points) and Chinese-character (105 points) sets, categories def, noise,
outlier and occlusion, every sample of each level (20; ``--samples`` takes fewer), both methods
register the template ``x1`` onto the degraded target ``y2a``. Ground truth: ``x1[i] <->
y2a[i]`` for the first ``min(len(y2), len(y2a))`` rows. Printed per category and level:

* registration error: mean ‖f(x1[i]) − y2a[i]‖ over the ground-truth rows (data units);
* correct-correspondence rate: the share of ground-truth rows i whose partner is y2a[i]. For
  TPS-RPM the partner comes from the thresholded H (h > 0.5, row and column maximum; rows
  without a match count as wrong); for CPD (and as a second TPS-RPM column) it is the data
  point nearest to the warped template point. Compare ``RPM nn`` with ``CPD nn`` for a
  like-for-like figure: ``RPM corr`` is stricter, since a fuzzy H leaves rows unmatched.

CPD is run as the authors' MATLAB code runs it: both sets normalised first (here to unit RMS
radius, each separately, as TPS-RPM does), 150 iterations at most, tolerance 1e-5, beta = 2,
lambda (pycpd's alpha) = 2, outlier weight w = ``--cpd-w`` (0 by default, as in both codes).
pycpd's own defaults (no normalisation, tolerance 1e-3) stop early on these unit-square sets.

pycpd is a development-only dependency (``pip install trackfw[dev]``). Usage::

    python benchmarks/pointsets_vs_cpd.py [--samples 20] [--data ../shared/data]

All 20 samples of all 44 levels take about 3 minutes on one core. Use them all for figures to
quote: with 10 samples, one sample that falls into a wrong minimum moves a level by 9 points.
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

for _variable in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_variable, "1")

import numpy as np  # noqa: E402 - after pinning the BLAS threads
import scipy.io  # noqa: E402
from scipy.spatial import cKDTree  # noqa: E402

from trackfw_plugins.maths.tps_rpm import tps_rpm  # noqa: E402
from trackfw_plugins.maths.tps_rpm_template import normalise_points  # noqa: E402

LEVELS = {"def": 5, "noise": 6, "outlier": 5, "occlusion": 6}
DEFAULT_DATA = Path(__file__).resolve().parents[2] / "shared" / "data"


def _nearest_rate(warped: np.ndarray, data: np.ndarray, ground_truth: int) -> float:
    nearest = cKDTree(data).query(warped[:ground_truth])[1]
    return float(np.mean(nearest == np.arange(ground_truth)))


def _evaluate(path: Path, cpd_w: float) -> dict[str, float]:
    from pycpd import DeformableRegistration  # dev-only dependency

    sample = scipy.io.loadmat(path)
    template = sample["x1"].astype(np.float64)
    data = sample["y2a"].astype(np.float64)
    ground_truth = min(len(sample["y2"]), len(data))
    truth = data[:ground_truth]

    start = time.perf_counter()
    result = tps_rpm(template, data)
    rpm_seconds = time.perf_counter() - start
    matches = result.matches
    correct = (matches[:, 0] < ground_truth) & (matches[:, 0] == matches[:, 1])
    rpm_error = np.mean(np.linalg.norm(result.warped_template[:ground_truth] - truth, axis=1))

    start = time.perf_counter()
    template_unit, _, _ = normalise_points(template)
    data_unit, data_centre, data_scale = normalise_points(data)
    registration = DeformableRegistration(
        X=data_unit,
        Y=template_unit,
        alpha=2.0,
        beta=2.0,
        w=cpd_w,
        max_iterations=150,
        tolerance=1e-5,
    )
    warped_unit, _ = registration.register()
    warped_cpd = data_centre + data_scale * warped_unit
    cpd_seconds = time.perf_counter() - start
    cpd_error = np.mean(np.linalg.norm(warped_cpd[:ground_truth] - truth, axis=1))
    return {
        "rpm_error": float(rpm_error),
        "rpm_rate": float(correct.sum() / ground_truth),
        "rpm_nearest": _nearest_rate(result.warped_template, data, ground_truth),
        "rpm_seconds": rpm_seconds,
        "cpd_error": float(cpd_error),
        "cpd_rate": _nearest_rate(warped_cpd, data, ground_truth),
        "cpd_seconds": cpd_seconds,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=20, help="samples per level (max 20)")
    parser.add_argument("--data", type=Path, default=DEFAULT_DATA, help="the shared data folder")
    parser.add_argument("--shapes", nargs="+", default=["fish", "chinese"])
    parser.add_argument("--categories", nargs="+", default=list(LEVELS))
    parser.add_argument("--cpd-w", type=float, default=0.0, help="CPD outlier weight w in [0, 1)")
    arguments = parser.parse_args()
    folder = arguments.data / "pointsets" / "chui_rangarajan_synthetic"
    if not folder.is_dir():
        raise SystemExit(f"point sets not found in {folder}; pass --data")

    header = (
        f"{'shape':8} {'category':10} {'lvl':>3} | {'RPM err':>8} {'RPM corr':>8} "
        f"{'RPM nn':>7} | {'CPD err':>8} {'CPD nn':>7} | {'RPM s':>6} {'CPD s':>6}"
    )
    print(header)
    print("-" * len(header))
    for shape in arguments.shapes:
        for category in arguments.categories:
            for level in range(1, LEVELS[category] + 1):
                rows = [
                    _evaluate(
                        folder / f"save_{shape}_{category}_{level}_{index}.mat", arguments.cpd_w
                    )
                    for index in range(1, arguments.samples + 1)
                ]
                mean = {key: float(np.mean([row[key] for row in rows])) for key in rows[0]}
                print(
                    f"{shape:8} {category:10} {level:>3} | {mean['rpm_error']:8.4f} "
                    f"{mean['rpm_rate']:8.3f} {mean['rpm_nearest']:7.3f} | "
                    f"{mean['cpd_error']:8.4f} {mean['cpd_rate']:7.3f} | "
                    f"{mean['rpm_seconds']:6.2f} {mean['cpd_seconds']:6.2f}",
                    flush=True,
                )


if __name__ == "__main__":
    main()
