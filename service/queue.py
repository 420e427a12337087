"""The one seam to the queue: a Celery app configured from the settings.

The API only sends tasks by name (:data:`RUN_JOB_TASK`); the worker package registers
the task under that name on an app made here, so both ends agree on the broker.
"""

from __future__ import annotations

import contextlib
import logging
import os
import sys
import time
import uuid
from queue import Empty
from typing import Any

from celery import Celery
from kombu.transport import filesystem
from kombu.utils.encoding import bytes_to_str, str_to_bytes
from kombu.utils.json import dumps, loads

from .config import Settings

__all__ = [
    "FILESYSTEM_TRANSPORT",
    "RUN_JOB_TASK",
    "FilesystemChannel",
    "FilesystemTransport",
    "make_celery",
    "worker_command",
]

log = logging.getLogger(__name__)

RUN_JOB_TASK = "inertia_id.run_job"

#: Celery's ``broker_transport`` for ``filesystem://``: kombu resolves the class by path
#: in every process that connects (the API's producer, the worker's consumer).
FILESYSTEM_TRANSPORT = f"{__name__}:FilesystemTransport"


# How often a consumer looks for messages claimed by a consumer that died before reading.
_ORPHAN_CHECK_INTERVAL_S = 10.0


# Why a subclass of kombu's filesystem transport and not a transport of our own: kombu's
# (maintained, and used by Celery for everything else it does with the broker: exchange
# tables, fanout to the workers' control queues, acknowledgements) is right but for two
# methods. Its ``_put`` opens the message file under its final name and only then locks
# and writes it, and its ``_get`` lists, moves and reads ``*.msg`` files without the lock:
# a consumer could take an empty or half-written file, and ``loads(b"")`` raised in the
# worker's main loop, which Celery treats as unrecoverable (the worker exited). The two
# methods below replace those; the file names, the folders and the options stay kombu's,
# so a stock kombu producer or consumer on the same folder still interoperates.
class FilesystemChannel(filesystem.Channel):
    """kombu's filesystem channel with an atomic ``_put`` and a ``_get`` that survives an
    unreadable message file.

    Options (``broker_transport_options``) beside kombu's own, each a folder on the
    queue's file system (a rename does not cross file systems):

    - ``staging_folder``: where ``_put`` writes a message before renaming it into the
      queue (default ``<data_folder_out>/.staging``);
    - ``claim_folder``: where ``_get`` renames a message to take it, so that exactly one
      consumer reads it (default ``<data_folder_in>/.claimed``);
    - ``rejected_folder``: where a message file that stayed unreadable for
      ``unreadable_grace_s`` (default 30 s) is moved aside, kept for inspection
      (default ``<data_folder_in>/.rejected``).

    A hidden folder in the queue's folder never matches the consumers' ``<queue>.msg``.
    """

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._orphans_checked_at = -_ORPHAN_CHECK_INTERVAL_S
        # Unreadable files already warned about (one warning each, not one per poll).
        self._unreadable_seen: set[str] = set()

    @property
    def staging_folder(self) -> str:
        return self._folder("staging_folder", self.data_folder_out, ".staging")

    @property
    def claim_folder(self) -> str:
        return self._folder("claim_folder", self.data_folder_in, ".claimed")

    @property
    def rejected_folder(self) -> str:
        return self._folder("rejected_folder", self.data_folder_in, ".rejected")

    @property
    def unreadable_grace_s(self) -> float:
        return float(self.transport_options.get("unreadable_grace_s", 30.0))

    def _folder(self, option: str, beside: str, default: str) -> str:
        folder = str(self.transport_options.get(option) or os.path.join(beside, default))
        os.makedirs(folder, exist_ok=True)
        return folder

    # kombu names the second argument ``message`` in its base class, ``payload`` here.
    def _put(self, queue: str, payload: Any, **kwargs: Any) -> None:  # type: ignore[override]
        """Put ``payload`` on ``queue``: written whole and flushed to disk under a name no
        consumer looks at, then renamed into the queue (a rename is atomic: a consumer sees
        the whole file or none)."""
        name = f"{round(time.monotonic() * 1000)}_{uuid.uuid4()}.{queue}.msg"
        target = os.path.join(self.data_folder_out, name)
        try:
            staged = os.path.join(self.staging_folder, name + ".part")
        except OSError as exc:
            raise filesystem.ChannelError(f"Cannot add file {name!r} to the queue") from exc
        data = str_to_bytes(dumps(payload))
        try:
            with open(staged, "xb") as file:
                file.write(data)
                file.flush()
                os.fsync(file.fileno())
            os.replace(staged, target)
        except OSError as exc:
            with contextlib.suppress(OSError):
                os.remove(staged)
            raise filesystem.ChannelError(f"Cannot add file {name!r} to the queue") from exc

    def _get(self, queue: str, timeout: float | None = None) -> dict[str, Any]:
        """The oldest readable message of ``queue``; an unreadable file is left in the
        queue (a producer may still be writing it) and skipped, and moved aside once it
        stayed unreadable for ``unreadable_grace_s``. Never raises for a message's
        content: an exception here stops Celery's worker."""
        self._recover_orphans()
        wanted = f"{queue}.msg"
        names = sorted(n for n in os.listdir(self.data_folder_in) if n.partition(".")[2] == wanted)
        for name in names:
            payload = self._take(name)
            if payload is not None:
                return payload
        raise Empty()

    def _recover_orphans(self) -> None:
        """Put back in the queue what a consumer claimed and never read nor put back (it
        died between the two), once it has sat claimed for the grace period."""
        now = time.monotonic()
        if now < self._orphans_checked_at + _ORPHAN_CHECK_INTERVAL_S:
            return
        self._orphans_checked_at = now
        try:
            names = os.listdir(self.claim_folder)
        except OSError:
            return
        for name in names:
            claimed = os.path.join(self.claim_folder, name)
            try:
                # A rename sets the file's ctime: the time it was claimed.
                if time.time() - os.stat(claimed).st_ctime <= self.unreadable_grace_s:
                    continue
                os.rename(claimed, os.path.join(self.data_folder_in, name))
            except OSError:
                continue
            log.warning("message file %s was claimed and never read: put back in the queue", name)

    def _take(self, name: str) -> dict[str, Any] | None:
        """The message in the queue's file ``name``, or None: taken by another consumer,
        or unreadable (then put back, or moved aside when it stayed so)."""
        source = os.path.join(self.data_folder_in, name)
        try:
            claimed = os.path.join(self.claim_folder, name)
            os.rename(source, claimed)  # exactly one consumer wins the rename
        except FileNotFoundError:
            return None  # another consumer took it
        except OSError as exc:
            log.warning("cannot take message file %s from the queue: %s", name, exc)
            return None
        reason, payload = "", None
        try:
            with open(claimed, "rb") as file:
                raw = file.read()
            if not raw:
                reason = "empty"
            else:
                payload = loads(bytes_to_str(raw))
                if not (isinstance(payload, dict) and isinstance(payload.get("properties"), dict)):
                    reason = "not a kombu message"
        except FileNotFoundError:
            return None  # put back by a consumer that found it orphaned: it is in the queue
        except (OSError, ValueError) as exc:  # ValueError: bad JSON, bad UTF-8
            reason = f"{type(exc).__name__}: {exc}"
        if not reason:
            self._unreadable_seen.discard(name)
            self._done(claimed)
            return payload
        self._unreadable(name, claimed, source, reason)
        return None

    def _done(self, claimed: str) -> None:
        """A delivered message's file: kept in ``processed_folder`` when kombu's
        ``store_processed`` asks for it, else removed (never left claimed: it would be
        put back and delivered again)."""
        if self.store_processed:
            kept = os.path.join(self.processed_folder, os.path.basename(claimed))
            with contextlib.suppress(OSError):
                os.replace(claimed, kept)
                return
        try:
            os.remove(claimed)
        except OSError as exc:
            log.warning("cannot remove the delivered message file %s: %s", claimed, exc)

    def _unreadable(self, name: str, claimed: str, source: str, reason: str) -> None:
        """Put an unreadable message file back in the queue (a producer that writes in
        place, as kombu's own does, may still be writing it: its writes land in the same
        file wherever it is renamed to), or, once it stayed unreadable for the grace
        period (by its last write), move it aside. Never deleted: it is kept to look at,
        and the job it may have carried is sent again from the ``jobs`` table."""
        try:
            age_s = time.time() - os.stat(claimed).st_mtime
        except OSError:
            age_s = 0.0
        if age_s > self.unreadable_grace_s:
            try:
                os.replace(claimed, os.path.join(self.rejected_folder, name))
            except OSError as exc:
                log.error("cannot move the unreadable message file %s aside: %s", name, exc)
            else:
                self._unreadable_seen.discard(name)
                log.error(
                    "message file %s unreadable for %.0f s (%s): moved aside to %s",
                    name,
                    age_s,
                    reason,
                    self.rejected_folder,
                )
                return
        try:
            os.rename(claimed, source)
        except OSError as exc:
            log.error("cannot put the unreadable message file %s back: %s", name, exc)
            return
        if name not in self._unreadable_seen:
            if len(self._unreadable_seen) > 1000:  # files another consumer dealt with
                self._unreadable_seen.clear()
            self._unreadable_seen.add(name)
            log.warning(
                "message file %s is unreadable (%s): left in the queue and skipped, read "
                "again at each poll, moved aside after %.0f s",
                name,
                reason,
                self.unreadable_grace_s,
            )


class FilesystemTransport(filesystem.Transport):
    """kombu's filesystem transport on :class:`FilesystemChannel`, with no host."""

    Channel = FilesystemChannel

    @property
    def default_connection_params(self) -> dict[str, object]:
        # kombu's virtual transports default to hostname 'localhost', so each clone of a
        # "filesystem://" connection (every publish: POST /jobs, the re-sender) logged
        # "WARNING: No hostname was supplied. Reverting to default 'localhost'". Harmless
        # (this transport reads only its folders, never a host) but it looked like a
        # misconfigured broker: a transport with no host has no default one.
        return {"port": self.default_port}


def make_celery(settings: Settings) -> Celery:
    """A Celery app on ``settings.broker_url`` (``filesystem://`` folders created)."""
    celery = Celery("inertia_id", broker=settings.broker_url)
    conf: dict[str, object] = {
        "task_serializer": "json",
        "accept_content": ["json"],
        "task_acks_late": True,
        "task_reject_on_worker_lost": True,
        "worker_prefetch_multiplier": 1,
        "broker_connection_retry_on_startup": True,
        "task_ignore_result": True,
    }
    if settings.broker_url.startswith("filesystem://"):
        folder = settings.broker_dir / "queue"
        folders = {
            option: settings.broker_dir / name
            for option, name in (
                ("processed_folder", "processed"),
                ("control_folder", "control"),
                ("staging_folder", "staging"),
                ("claim_folder", "claimed"),
                ("rejected_folder", "rejected"),
            )
        }
        for path in (folder, *folders.values()):
            path.mkdir(parents=True, exist_ok=True)
        # Our subclass of kombu's transport: messages are written atomically and an
        # unreadable one is skipped, not fatal (see FilesystemChannel).
        conf["broker_transport"] = FILESYSTEM_TRANSPORT
        conf["broker_transport_options"] = {
            "data_folder_in": str(folder),
            "data_folder_out": str(folder),
            **{option: str(path) for option, path in folders.items()},
            "store_processed": False,
            # The transport polls its folder (kombu's default: every second); listing a
            # folder ten times a second is cheap, and a job starts within 0.1 s.
            "polling_interval": 0.1,
        }
    elif settings.broker_url.startswith(("redis://", "rediss://")):
        # Longer than the longest job: an unacknowledged message is redelivered after it.
        conf["broker_transport_options"] = {"visibility_timeout": 12 * 3600}
    celery.conf.update(conf)
    return celery


def worker_command(name: str, *, log_level: str = "INFO", pool: str | None = None) -> list[str]:
    """The command line of one worker process: a ``celery worker`` on the app of
    :mod:`worker.celery_app`, in this interpreter, running one job at a time, named
    ``name@<host>``; ``pool`` is Celery's ``--pool`` (its own default when None)."""
    command = [sys.executable, "-m", "celery", "-A", "worker.celery_app", "worker"]
    command += ["--concurrency=1", "-n", f"{name}@%h", f"--loglevel={log_level}"]
    return command if pool is None else [*command, f"--pool={pool}"]
