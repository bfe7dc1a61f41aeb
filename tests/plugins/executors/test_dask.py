"""The Dask executor gives the local executor's table (skipped without Dask distributed)."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

pytest.importorskip("distributed")


def test_dask_local_cluster_gives_the_local_table(sweep, tmp_path: Path) -> None:
    _, local_rows = sweep(tmp_path / "local")
    result, rows = sweep(tmp_path / "dask", executor="dask", jobs=2)
    assert result.count("done") == 4 and not result.failures, result.failures
    assert rows == local_rows
    # The jobs ran in the cluster's worker processes, not here.
    assert all(int(job.worker.rsplit(":", 1)[1]) != os.getpid() for job in result.results)
    assert all(job.cache in ("hit", "miss") for job in result.results)
