"""The filesystem broker (``service.queue.FilesystemTransport``, kombu's transport with an
atomic ``_put`` and a ``_get`` that survives an unreadable message file).

kombu's own ``_put`` opened ``<ms>_<uuid>.<queue>.msg`` under its final name, then locked
and wrote it, and its ``_get`` read such files without the lock: a consumer could read an
empty or partial file, ``loads(b"")`` raised in the worker's main loop and Celery stopped
the worker ("Unrecoverable error"). An empty ``.msg`` file in the queue folder while a
worker is idle reproduced it every time.
"""

from __future__ import annotations

import json
import logging
import os
import threading
import time
import uuid
from collections.abc import Iterator
from pathlib import Path
from queue import Empty
from typing import TYPE_CHECKING, Any

import pytest
from kombu import Connection

import service.queue as queue_module
from service.config import Settings
from service.queue import FilesystemChannel, FilesystemTransport, make_celery

if TYPE_CHECKING:
    from conftest import Service

QUEUE = "celery"
TRAIN = {"sequence": [[4, 4, 4, 0, 0, 0]] * 4, "metric": "euclidean", "n_realisations": 5}


def _message(body: Any, tag: str | None = None) -> dict[str, Any]:
    """A payload as kombu's virtual channel stores it."""
    return {
        "body": json.dumps(body),
        "content-encoding": "utf-8",
        "content-type": "application/json",
        "headers": {},
        "properties": {
            "delivery_tag": tag or str(uuid.uuid4()),
            "delivery_info": {"exchange": "", "routing_key": QUEUE},
            "body_encoding": "utf-8",
            "priority": 0,
        },
    }


def _file_name(age_ms: int = 0) -> str:
    """A message file's name as kombu's producer makes it, ``age_ms`` older than now."""
    return f"{round(time.monotonic() * 1000) - age_ms}_{uuid.uuid4()}.{QUEUE}.msg"


def _kept_in_queue(path: Path, within_s: float = 5.0) -> bool:
    """Whether the message file ``path`` is in its queue, or claimed for a moment by a
    consumer's poll (it renames the file into ``.claimed`` and, unreadable, back):
    looked for in both until seen in one."""
    claimed = path.parent / ".claimed" / path.name
    deadline = time.monotonic() + within_s
    while time.monotonic() < deadline:
        if path.exists() or claimed.exists():
            return True
        time.sleep(0.01)
    return False


@pytest.fixture
def broker(tmp_path: Path) -> Iterator[tuple[FilesystemChannel, Path]]:
    """A channel of our transport on folders in ``tmp_path``, and its queue folder."""
    folder = tmp_path / "queue"
    folder.mkdir()
    options = {
        "data_folder_in": str(folder),
        "data_folder_out": str(folder),
        "control_folder": str(tmp_path / "control"),
        "staging_folder": str(tmp_path / "staging"),
        "claim_folder": str(tmp_path / "claimed"),
        "rejected_folder": str(tmp_path / "rejected"),
    }
    with Connection("filesystem://", transport=FilesystemTransport, transport_options=options) as c:
        channel = c.default_channel
        assert isinstance(channel, FilesystemChannel)
        yield channel, folder


def _queued(folder: Path) -> list[Path]:
    """The files a consumer would take: kombu's ``<anything>.<queue>.msg``."""
    return sorted(p for p in folder.iterdir() if p.name.partition(".")[2] == f"{QUEUE}.msg")


def test_make_celery_puts_the_filesystem_broker_on_our_transport(tmp_path: Path) -> None:
    settings = Settings(
        INERTIA_ID_DATA_DIR=tmp_path / "data",
        DATABASE_URL=f"sqlite:///{tmp_path / 'data' / 'db.sqlite'}",
        BROKER_URL="filesystem://",
    )
    celery = make_celery(settings)
    with celery.connection_for_write() as connection:
        assert connection.get_transport_cls() is FilesystemTransport
        assert isinstance(connection.default_channel, FilesystemChannel)
    with celery.connection_for_read() as connection:
        assert connection.get_transport_cls() is FilesystemTransport
    options = celery.conf.broker_transport_options
    for option in ("staging_folder", "claim_folder", "rejected_folder"):
        # Beside the queue folder (same file system), never inside it.
        assert Path(options[option]).parent == Path(options["data_folder_in"]).parent
        assert Path(options[option]).is_dir()

    celery.send_task("inertia_id.run_job", args=["job-1"])
    (message,) = (settings.broker_dir / "queue").glob("*.msg")
    assert json.loads(message.read_bytes())["headers"]["argsrepr"] == "['job-1']"
    assert not list((settings.broker_dir / "staging").iterdir())
    # A Redis broker keeps kombu's own transport.
    redis = make_celery(settings.model_copy(update={"broker_url": "redis://127.0.0.1:1/0"}))
    assert not redis.conf.broker_transport


def test_sending_a_job_on_the_filesystem_broker_logs_no_warning(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """Each send (``POST /jobs``) logged kombu's "No hostname was supplied. Reverting to
    default 'localhost'" in serve's log: a filesystem transport has no host to supply."""
    settings = Settings(
        INERTIA_ID_DATA_DIR=tmp_path / "data",
        DATABASE_URL=f"sqlite:///{tmp_path / 'data' / 'db.sqlite'}",
        BROKER_URL="filesystem://",
    )
    celery = make_celery(settings)
    with caplog.at_level(logging.WARNING):
        celery.send_task("inertia_id.run_job", args=["job-1"])
        celery.send_task("inertia_id.run_job", args=["job-2"])
    assert len(list((settings.broker_dir / "queue").glob("*.msg"))) == 2
    warned = [r.getMessage() for r in caplog.records if r.levelno >= logging.WARNING]
    assert warned == [], warned


def test_put_never_shows_a_partial_file_under_the_consumers_name(
    broker: tuple[FilesystemChannel, Path], monkeypatch: pytest.MonkeyPatch
) -> None:
    channel, folder = broker
    payload = _message({"blob": "x" * 200_000})
    seen_while_writing: list[list[Path]] = []
    real_fsync = os.fsync

    def fsync(fd: int) -> None:
        # The whole message is written and being flushed: nothing in the queue yet.
        seen_while_writing.append(_queued(folder))
        real_fsync(fd)

    monkeypatch.setattr(queue_module.os, "fsync", fsync)
    channel._put(QUEUE, payload)
    assert seen_while_writing == [[]]
    (message,) = _queued(folder)
    assert json.loads(message.read_bytes()) == payload
    # The staging file is gone, renamed into the queue.
    assert not list(Path(channel.staging_folder).iterdir())
    assert [p.name for p in folder.iterdir()] == [message.name]


def test_put_and_get_race_every_message_whole_and_once(
    broker: tuple[FilesystemChannel, Path],
) -> None:
    """A consumer polling while a producer writes large messages reads each one whole,
    exactly once, and never fails."""
    channel, _folder = broker
    n = 60
    got: list[dict[str, Any]] = []
    errors: list[BaseException] = []
    done = threading.Event()

    def consume() -> None:
        deadline = time.monotonic() + 60
        while len(got) < n and time.monotonic() < deadline:
            try:
                got.append(channel._get(QUEUE))
            except Empty:
                pass
            except BaseException as exc:
                errors.append(exc)
                return
        done.set()

    consumer = threading.Thread(target=consume)
    consumer.start()
    sent = [_message({"i": i, "blob": "y" * 100_000}, tag=f"tag-{i}") for i in range(n)]
    for payload in sent:
        channel._put(QUEUE, payload)
    consumer.join(90)
    assert not errors, errors
    assert sorted(got, key=lambda p: p["properties"]["delivery_tag"]) == sorted(
        sent, key=lambda p: p["properties"]["delivery_tag"]
    )


@pytest.mark.parametrize("content", [b"", b'{"body": "eyJ', b"\xff\xfe", b"[1, 2]"])
def test_get_skips_an_unreadable_file_and_delivers_the_next(
    broker: tuple[FilesystemChannel, Path], content: bytes, caplog: pytest.LogCaptureFixture
) -> None:
    channel, folder = broker
    bad = folder / _file_name(age_ms=5000)  # the oldest: first in the consumer's order
    bad.write_bytes(content)
    with pytest.raises(Empty), caplog.at_level(logging.WARNING, "service.queue"):
        channel._get(QUEUE)
    assert bad.read_bytes() == content, "an unreadable file stays in the queue, untouched"
    assert any(bad.name in r.getMessage() for r in caplog.records)

    payload = _message({"job": 1})
    channel._put(QUEUE, payload)
    assert channel._get(QUEUE) == payload
    with pytest.raises(Empty):
        channel._get(QUEUE)
    assert _queued(folder) == [bad]
    # One warning for the file, not one per poll.
    warned = [r for r in caplog.records if bad.name in r.getMessage()]
    assert len(warned) == 1


def test_a_file_written_in_place_is_read_once_its_writer_is_done(
    broker: tuple[FilesystemChannel, Path],
) -> None:
    """A producer that writes the final name in place (kombu's own ``_put``, say an API of
    an earlier version) is read once complete: the early reads put it back."""
    channel, folder = broker
    payload = _message({"job": 2})
    data = json.dumps(payload).encode()
    path = folder / _file_name()
    with open(path, "wb", buffering=0) as writer:
        with pytest.raises(Empty):
            channel._get(QUEUE)  # empty
        writer.write(data[:10])
        with pytest.raises(Empty):
            channel._get(QUEUE)  # partial
        writer.write(data[10:])  # the open file is the one put back
    assert channel._get(QUEUE) == payload
    assert not _queued(folder)


def test_a_file_unreadable_past_the_grace_is_moved_aside_not_deleted(
    broker: tuple[FilesystemChannel, Path], caplog: pytest.LogCaptureFixture
) -> None:
    channel, folder = broker
    bad = folder / _file_name()
    bad.write_bytes(b"")
    with pytest.raises(Empty):
        channel._get(QUEUE)
    assert _queued(folder) == [bad]
    old = time.time() - channel.unreadable_grace_s - 5
    os.utime(bad, (old, old))
    with pytest.raises(Empty), caplog.at_level(logging.ERROR, "service.queue"):
        channel._get(QUEUE)
    assert not _queued(folder)
    assert (Path(channel.rejected_folder) / bad.name).exists()
    assert any("moved aside" in r.getMessage() for r in caplog.records)


def test_a_message_claimed_by_a_consumer_that_died_goes_back_to_the_queue(
    broker: tuple[FilesystemChannel, Path], monkeypatch: pytest.MonkeyPatch
) -> None:
    channel, folder = broker
    payload = _message({"job": 3})
    channel._put(QUEUE, payload)
    (message,) = _queued(folder)
    # Taken by a consumer that died before reading it.
    message.rename(Path(channel.claim_folder) / message.name)
    with pytest.raises(Empty):
        channel._get(QUEUE)  # claimed just now: not an orphan yet
    monkeypatch.setitem(channel.transport_options, "unreadable_grace_s", 0.0)
    channel._orphans_checked_at = -1e9  # due for a check
    time.sleep(0.01)
    assert channel._get(QUEUE) == payload


@pytest.mark.parametrize("deployment", ["filesystem"], indirect=True)
def test_worker_survives_empty_and_partial_message_files(deployment: Service) -> None:
    """The reviewer's case: an empty ``.msg`` file in the queue folder while a worker is
    idle (and a partial one); the worker stays up and runs the next job."""
    worker = deployment.start_worker()
    folder = deployment.settings.broker_dir / "queue"
    empty = folder / _file_name(age_ms=2000)
    partial = folder / _file_name(age_ms=1000)
    for path, data in ((empty, b""), (partial, json.dumps(_message({"job": "x"}))[:40].encode())):
        # Each appears whole (written beside, then renamed in): written in place, the
        # partial file could be polled while still empty, and warned about as empty.
        staged = folder.parent / path.name
        staged.write_bytes(data)
        os.replace(staged, path)
    time.sleep(1.5)  # some fifteen polls of the queue
    assert worker.alive(), worker.log()

    job = deployment.wait_for(deployment.submit("train", TRAIN, seed=5))
    assert job.status == "succeeded", job.error
    assert worker.alive(), worker.log()
    assert job.worker == worker.name
    log = worker.log(200_000)
    assert "Unrecoverable error" not in log and "Traceback" not in log
    # Each skipped with one warning that names it and why.
    assert f"message file {empty.name} is unreadable (empty)" in log
    assert f"message file {partial.name} is unreadable (JSONDecodeError" in log
    assert log.count(empty.name) == 1
    # Left in the queue (nothing deleted), to be retried and, after the grace, moved aside.
    # The worker claims each at every poll (renames it into the queue's .claimed folder) and
    # puts it back: the file is in one of the two, and which depends on the moment we look.
    assert _kept_in_queue(empty) and _kept_in_queue(partial)
    assert not any((folder / ".rejected" / path.name).exists() for path in (empty, partial))
