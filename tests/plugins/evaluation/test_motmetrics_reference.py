"""Box mode against py-motmetrics' asserted values on TUD-Campus and TUD-Stadtmitte (atol 1e-3)."""

from __future__ import annotations

from pathlib import Path

import pytest

from trackfw.formats import read_mot_text, rows_by_frame
from trackfw_plugins.evaluation.clear_mot import ClearMotCounts, build_sequence, clear_mot
from trackfw_plugins.evaluation.hota import HotaCounts, hota_counts
from trackfw_plugins.evaluation.identity import IdentityCounts, identity_counts

# Columns: IDF1 IDP IDR Rcll Prcn GT MT PT ML FP FN IDs FM MOTA MOTP (EXPECTED_VALUES.md).
EXPECTED = {
    "TUD-Campus": (
        0.557659,
        0.729730,
        0.451253,
        0.582173,
        0.941441,
        8,
        1,
        6,
        1,
        13,
        150,
        7,
        7,
        0.526462,
        0.277201,
    ),
    "TUD-Stadtmitte": (
        0.644619,
        0.819760,
        0.531142,
        0.608997,
        0.939920,
        10,
        5,
        4,
        1,
        45,
        452,
        7,
        6,
        0.564014,
        0.345904,
    ),
    "OVERALL": (
        0.624296,
        0.799176,
        0.512211,
        0.602640,
        0.940268,
        18,
        6,
        10,
        2,
        58,
        602,
        14,
        13,
        0.555116,
        0.330177,
    ),
}
EXPECTED_HOTA = {
    "TUD-Campus": (0.39139744, 0.41804703, 0.36912068),
    "OVERALL": (0.39995709, 0.39768329, 0.41244953),
}


def _row(clear: ClearMotCounts, identity: IdentityCounts) -> tuple[float, ...]:
    return (
        identity.idf1, identity.idp, identity.idr, clear.recall, clear.precision,
        clear.n_unique_objects, clear.mostly_tracked, clear.partially_tracked, clear.mostly_lost,
        clear.n_false_positives, clear.n_misses, clear.n_switches, clear.n_fragmentations,
        clear.mota, clear.motp,
    )  # fmt: skip


def _evaluate(folder: Path) -> tuple[ClearMotCounts, IdentityCounts, HotaCounts]:
    ground_truth = rows_by_frame(read_mot_text(folder / "gt.txt"), "box", frame_offset=0)
    hypotheses = rows_by_frame(read_mot_text(folder / "test.txt"), "box", frame_offset=0)
    sequence = build_sequence(ground_truth, hypotheses)
    return (
        clear_mot(sequence, "box", 0.5),
        identity_counts(sequence, "box", 0.5),
        hota_counts(sequence, "box"),
    )


def test_tud_sequences_match_motmetrics(shared_data: Path) -> None:
    root = shared_data / "motmetrics_data"
    if not (root / "TUD-Campus" / "gt.txt").is_file():
        pytest.skip(f"py-motmetrics data not found under {root}")
    results = {name: _evaluate(root / name) for name in ("TUD-Campus", "TUD-Stadtmitte")}
    campus, stadtmitte = results["TUD-Campus"], results["TUD-Stadtmitte"]
    results["OVERALL"] = (
        campus[0] + stadtmitte[0],
        campus[1] + stadtmitte[1],
        campus[2] + stadtmitte[2],
    )
    for name, expected in EXPECTED.items():
        clear, identity, _ = results[name]
        assert _row(clear, identity) == pytest.approx(expected, abs=1e-3), name
    for name, (hota, det_a, ass_a) in EXPECTED_HOTA.items():
        summary = results[name][2].summary()
        assert (summary["HOTA"], summary["DetA"], summary["AssA"]) == pytest.approx(
            (hota, det_a, ass_a), abs=1e-3
        ), name
