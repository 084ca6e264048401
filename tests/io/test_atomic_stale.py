"""A temporary file that a killed writer left is removed when its target is next written
(issue 30: a sweep killed while saving ratios.png left ``.ratios.png.*.tmp`` for good)."""

from __future__ import annotations

from knotmm.io.atomic import replacing, write_text_atomic


def _left(directory):
    return sorted(p.name for p in directory.iterdir())


def test_a_killed_writers_temporary_goes_when_the_target_is_written(tmp_path):
    # what SIGKILL inside write_atomic / replacing leaves (their naming)
    (tmp_path / ".summary.csv.k2x9ab12.tmp").write_text("half")
    (tmp_path / ".movie.gif.q81zabcd.tmp.gif").write_bytes(b"GIF8")
    (tmp_path / ".other.csv.k2x9ab12.tmp").write_text("another file's")
    (tmp_path / ".summary.csv.notes").write_text("not a temporary")
    write_text_atomic(tmp_path / "summary.csv", "a,b\n")
    assert _left(tmp_path) == [".movie.gif.q81zabcd.tmp.gif", ".other.csv.k2x9ab12.tmp",
                               ".summary.csv.notes", "summary.csv"]
    with replacing(tmp_path / "movie.gif") as tmp:
        tmp.write_bytes(b"GIF89a")
    assert _left(tmp_path) == [".other.csv.k2x9ab12.tmp", ".summary.csv.notes", "movie.gif",
                               "summary.csv"]
    assert (tmp_path / "summary.csv").read_text() == "a,b\n"


def test_taking_a_directory_lock_removes_killed_writers_temporaries(tmp_path):
    """A sweep killed while saving ratios.png and run again may not rewrite ratios.png (the
    default-set fuzz case left ``.ratios.png.*.tmp``): the command that takes the
    directory's lock removes them, and nothing else."""
    from knotmm.io.rundir import RunLock

    (tmp_path / ".ratios.png.c3ys8j7e.tmp").write_bytes(b"\x89PNG")
    (tmp_path / ".analysis.json.abcdefgh.tmp.json").write_text("{")
    (tmp_path / "ratios.png").write_bytes(b"\x89PNG whole")
    (tmp_path / ".hidden.tmp").write_text("not knotmm's")
    lock = RunLock(tmp_path, "sweep")
    try:
        assert _left(tmp_path) == [".hidden.tmp", ".knotmm.lock", "ratios.png"]
    finally:
        lock.release()
