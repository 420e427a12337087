"""The flock files of worker incarnations beside a SQLite database (worker.incarnation):
those left by workers that died without removing theirs are removed by the next worker
that starts, a live worker's kept."""

from __future__ import annotations

from pathlib import Path

from worker.incarnation import Life


def test_a_starting_worker_removes_the_lock_files_of_dead_ones_and_keeps_live_ones(
    tmp_path: Path,
) -> None:
    url = f"sqlite:///{tmp_path / 'data dir' / 'inertia-id.db'}"
    live = Life(url, "live")
    assert live.hold()
    folder = tmp_path / "data dir" / "inertia-id.db.incarnations"
    # As `inertia-id serve`'s stop (SIGKILL once the job is handed back) or a kill -9
    # leaves them: the file is there, nobody holds its lock.
    for dead in ("dead1", "dead2"):
        (folder / f"{dead}.lock").touch()
    new = Life(url, "new")
    try:
        assert new.hold()
        assert sorted(p.name for p in folder.iterdir()) == ["live.lock", "new.lock"]
    finally:
        new.release()
        live.release()
    assert list(folder.iterdir()) == []
