"""Milliseconds per descriptor for the appearance (E_a), LOMO and GOG descriptors.

A short run on synthetic pixels (no data needed)::

    python benchmarks/descriptor_speed.py --repeats 5

Figures depend on the machine and on its load; BLAS is limited to one thread inside GOG.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable

import cv2
import numpy as np

from trackfw_plugins.maths.appearance import appearance_descriptors
from trackfw_plugins.maths.gog import gog_descriptor
from trackfw_plugins.maths.lomo import lomo_descriptor
from trackfw_plugins.maths.reid_crop import reid_crops


def _milliseconds(function: Callable[[], object], repeats: int) -> float:
    function()  # warm caches (HOG object, window layouts, colour tables)
    start = time.perf_counter()
    for _ in range(repeats):
        function()
    return (time.perf_counter() - start) / repeats * 1000.0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5, help="timed runs per measurement")
    parser.add_argument("--points", type=int, default=10, help="points per frame")
    arguments = parser.parse_args()

    rng = np.random.default_rng(0)
    frame = cv2.resize(rng.integers(0, 256, size=(108, 192, 3), dtype=np.uint8), (1920, 1080))
    points = np.column_stack(
        [rng.uniform(0, 1920, arguments.points), rng.uniform(0, 1080, arguments.points)]
    )
    crops = reid_crops(frame, points)
    crop = crops[0]

    per_frame = _milliseconds(lambda: appearance_descriptors(frame, points), arguments.repeats)
    crop_time = _milliseconds(lambda: reid_crops(frame, points), arguments.repeats)
    lomo = _milliseconds(lambda: lomo_descriptor(crop), arguments.repeats)
    gog = _milliseconds(lambda: gog_descriptor(crop), arguments.repeats)

    print(f"appearance (80x80, D=2981): {per_frame / arguments.points:8.2f} ms per point")
    print(f"re-ID body crop (128x48):   {crop_time / arguments.points:8.2f} ms per point")
    print(f"LOMO (D={lomo_descriptor(crop).size}):         {lomo:8.2f} ms per crop")
    print(f"GOG  (D={gog_descriptor(crop).size}):         {gog:8.2f} ms per crop")


if __name__ == "__main__":
    main()
