"""Sweep tables: a row cut short by a crash, a full disk while a row is appended or the Parquet copy
is written; the rows already written are kept and the message names the table."""
import errno
import sys
from pathlib import Path

import pytest

import demkit as dk
from demkit.sweep import read_table

from .conftest import failing_writes, injected

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
from sweep_tasks import square  # noqa: E402

pytestmark = pytest.mark.reliability

GRID = {"x": [1.0, 2.0, 3.0, 4.0]}


def cells(rows):
    """The rows without their wall times."""
    return [{k: v for k, v in r.items() if k != "wall_s"} for r in rows]


def test_a_row_cut_short_by_a_crash_is_dropped_and_its_point_runs_again(tmp_path, capsys):
    whole = cells(dk.sweep(square, GRID, tmp_path / "whole.csv", workers=1, progress=False))
    table = tmp_path / "t.csv"
    dk.sweep(square, GRID, table, workers=1, progress=False)
    text = table.read_text()
    table.write_text(text[:text.rstrip().rfind("\n") + 6])  # the last row half written
    injected("sweep table row cut short")
    again = cells(dk.sweep(square, GRID, table, workers=1, progress=False))
    err = capsys.readouterr().err
    assert f"{table}: its last row was cut short" in err and "that point runs again" in err, err
    assert again == whole


def test_a_full_disk_while_appending_keeps_the_rows_before(tmp_path, monkeypatch):
    table = tmp_path / "sweep" / "t.csv"
    calls = []

    def filling(point):
        calls.append(point)
        if len(calls) == 3:  # the disk fills up while the third point runs
            failing_writes(monkeypatch, tmp_path / "sweep")
        return square(point)
    injected("full disk while a sweep row is appended")
    with pytest.raises(OSError, match=rf"could not add a row to the sweep table {table} \(No space left on device\): "
                                      r"the 2 rows before it are kept"):
        dk.sweep(filling, GRID, table, workers=1, progress=False)
    monkeypatch.undo()
    assert [r["x"] for r in read_table(table)] == [1.0, 2.0]
    rows = dk.sweep(square, GRID, table, workers=1, progress=False)  # finishes the rest
    assert [r["y"] for r in rows] == [1.0, 4.0, 9.0, 16.0]


def test_a_parquet_copy_that_cannot_be_written_leaves_the_old_one_whole(tmp_path, monkeypatch):
    pytest.importorskip("pyarrow")
    import pyarrow.parquet as pq
    dk.sweep(square, {"x": [1.0, 2.0]}, tmp_path / "t.parquet", workers=1, progress=False)
    before = (tmp_path / "t.parquet").read_bytes()
    real = pq.write_table

    def full(table, where, *args, **kwargs):
        with open(where, "wb") as fh:
            fh.write(b"PAR1 half")
        raise OSError(errno.ENOSPC, "No space left on device", str(where))
    monkeypatch.setattr(pq, "write_table", full)
    injected("full disk while the Parquet table is written")
    with pytest.raises(OSError, match="No space left on device"):
        dk.sweep(square, GRID, tmp_path / "t.parquet", workers=1, progress=False)
    monkeypatch.setattr(pq, "write_table", real)
    assert (tmp_path / "t.parquet").read_bytes() == before
    assert not list(tmp_path.glob("*partial*"))
    assert len(read_table(tmp_path / "t.csv")) == 4  # the CSV, the working table, has every row
