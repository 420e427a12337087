"""The service's settings refuse values out of range, one line each naming the variable."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
from pydantic import ValidationError
from service_support import ROOT, clean_env, free_port

from service.config import (
    LONGEST_S,
    MAX_COMPUTE_QUEUE,
    MAX_COMPUTE_THREADS,
    Settings,
    setting_problems,
)

#: A value each setting took before it had a range, and the service started with it:
#: a body limit of -5 bytes, a heartbeat timeout of -1 s, a wait of 1e12 s that
#: overflows ``threading.Event.wait`` when it is first used, ...
OUT_OF_RANGE = [
    ("INERTIA_ID_PORT", "0"),
    ("INERTIA_ID_PORT", "65536"),
    ("INERTIA_ID_MAX_BODY_BYTES", "-5"),
    ("INERTIA_ID_MAX_BODY_BYTES", "0"),
    ("INERTIA_ID_MAX_PAGE_SIZE", "0"),
    ("INERTIA_ID_MAX_METRIC_POINTS", "1"),
    ("INERTIA_ID_HEARTBEAT_INTERVAL_S", "0"),
    ("INERTIA_ID_HEARTBEAT_INTERVAL_S", "-inf"),
    ("INERTIA_ID_HEARTBEAT_TIMEOUT_S", "-1"),
    ("INERTIA_ID_HEARTBEAT_TIMEOUT_S", "inf"),
    ("INERTIA_ID_MAX_ATTEMPTS", "0"),
    ("INERTIA_ID_UNSENT_GRACE_S", "-1"),
    ("INERTIA_ID_UNSENT_GRACE_S", "0"),
    ("INERTIA_ID_RESEND_AFTER_S", "0"),
    ("INERTIA_ID_RESEND_AFTER_S", "1e12"),
    ("INERTIA_ID_WORKER_MAX_JOBS", "0"),
    ("INERTIA_ID_WORKER_MAX_MEMORY_MB", "-1"),
    ("INERTIA_ID_WORKER_START_TIMEOUT_S", "1e12"),
    ("INERTIA_ID_QUEUE_STALL_S", "1e12"),
    ("INERTIA_ID_CLASSIFIER_CACHE", "-1"),
    ("INERTIA_ID_COMPUTE_THREADS", "0"),
    ("INERTIA_ID_COMPUTE_THREADS", str(MAX_COMPUTE_THREADS + 1)),
    ("INERTIA_ID_COMPUTE_THREADS", str(10**9)),
    ("INERTIA_ID_COMPUTE_QUEUE", "-1"),
    ("INERTIA_ID_COMPUTE_QUEUE", str(MAX_COMPUTE_QUEUE + 1)),
    ("INERTIA_ID_COMPUTE_QUEUE", str(10**9)),
    ("INERTIA_ID_COMPUTE_WAIT_S", "inf"),
    ("INERTIA_ID_VERDICT_TIMEOUT_S", "inf"),
    ("INERTIA_ID_JOB_TIME_LIMIT_S", "1e12"),
    # Under a second, as a job's own time_limit_s: every training and sweep would fail.
    ("INERTIA_ID_JOB_TIME_LIMIT_S", "0.5"),
    ("INERTIA_ID_JOB_TIME_LIMIT_S", "1e-9"),
    ("INERTIA_ID_REQUEST_HEAD_TIMEOUT_S", "1e12"),
    ("INERTIA_ID_REQUEST_BODY_TIMEOUT_S", "1e12"),
    # Below 1 s every statement of the API was cut (50 of 50 at 1e-3 s): a 503 each.
    ("INERTIA_ID_DATABASE_ANSWER_TIMEOUT_S", "0.001"),
    ("INERTIA_ID_DATABASE_ANSWER_TIMEOUT_S", "1e-9"),
    ("INERTIA_ID_DATABASE_ANSWER_TIMEOUT_S", "1e308"),
]

#: The edges of the same ranges, which are accepted.
AT_THE_EDGE = [
    ("INERTIA_ID_PORT", "1"),
    ("INERTIA_ID_PORT", "65535"),
    ("INERTIA_ID_MAX_BODY_BYTES", "1"),
    ("INERTIA_ID_MAX_PAGE_SIZE", "1"),
    ("INERTIA_ID_MAX_METRIC_POINTS", "2"),
    ("INERTIA_ID_HEARTBEAT_INTERVAL_S", "0.001"),
    ("INERTIA_ID_MAX_ATTEMPTS", "1"),
    ("INERTIA_ID_UNSENT_GRACE_S", str(LONGEST_S)),
    ("INERTIA_ID_WORKER_MAX_JOBS", "1"),
    ("INERTIA_ID_WORKER_MAX_MEMORY_MB", "1"),
    ("INERTIA_ID_CLASSIFIER_CACHE", "0"),
    ("INERTIA_ID_COMPUTE_THREADS", "1"),
    ("INERTIA_ID_COMPUTE_THREADS", str(MAX_COMPUTE_THREADS)),
    ("INERTIA_ID_COMPUTE_QUEUE", "0"),
    ("INERTIA_ID_COMPUTE_QUEUE", str(MAX_COMPUTE_QUEUE)),
    ("INERTIA_ID_JOB_TIME_LIMIT_S", "1"),
    ("INERTIA_ID_JOB_TIME_LIMIT_S", str(LONGEST_S)),
    ("INERTIA_ID_DATABASE_ANSWER_TIMEOUT_S", "1"),
    ("INERTIA_ID_DATABASE_ANSWER_TIMEOUT_S", str(LONGEST_S)),
]


def test_every_numeric_setting_has_a_lower_bound_and_every_duration_an_upper_one() -> None:
    """A new setting cannot come without a range: each number has a lower bound, each
    duration (``_s``) an upper one and no inf or nan."""
    for field, info in Settings.model_fields.items():
        if info.annotation not in (int, float):
            continue
        kinds = {type(rule).__name__ for rule in info.metadata}
        assert kinds & {"Ge", "Gt"}, f"{info.alias} has no lower bound"
        if field.endswith("_s"):
            assert "Le" in kinds and "AllowInfNan" in kinds, f"{info.alias} has no ceiling"
    assert {"Ge", "Le"} <= {type(r).__name__ for r in Settings.model_fields["port"].metadata}


@pytest.mark.parametrize(("name", "value"), OUT_OF_RANGE)
def test_a_setting_out_of_range_is_refused_naming_it(name: str, value: str) -> None:
    with pytest.raises(ValidationError) as refused:
        Settings(**{name: value})
    (line,) = setting_problems(refused.value)
    assert line.startswith(f"{name}={value!r}: Input should be ")


@pytest.mark.parametrize(("name", "value"), AT_THE_EDGE)
def test_a_setting_at_the_edge_of_its_range_is_accepted(name: str, value: str) -> None:
    settings = Settings(**{name: value})
    field = next(f for f, info in Settings.model_fields.items() if info.alias == name)
    assert getattr(settings, field) == type(getattr(settings, field))(value)


@pytest.mark.parametrize(("stall", "resend"), [("30", "30"), ("20", "30"), ("5", "6")])
def test_a_queue_stall_not_longer_than_the_resend_wait_is_refused(stall: str, resend: str) -> None:
    """/health called the queue stalled before the re-sender's turn to send a lost
    message again."""
    with pytest.raises(ValidationError) as refused:
        Settings(INERTIA_ID_QUEUE_STALL_S=stall, INERTIA_ID_RESEND_AFTER_S=resend)
    (line,) = setting_problems(refused.value)
    assert line.startswith(
        f"INERTIA_ID_QUEUE_STALL_S={float(stall):g} must be longer than "
        f"INERTIA_ID_RESEND_AFTER_S={float(resend):g}"
    )
    assert Settings(INERTIA_ID_QUEUE_STALL_S="31", INERTIA_ID_RESEND_AFTER_S="30")


@pytest.mark.parametrize(
    ("entry", "bare"),
    [
        ("api:8000", "api"),
        ("[::1]:8000", "[::1]"),
        ("https://ops.example.org", "ops.example.org"),
        ("ops.example.org/inertia", "ops.example.org"),
    ],
)
def test_an_allowed_host_with_a_port_or_scheme_is_refused_naming_the_bare_name(
    entry: str, bare: str
) -> None:
    """The Host header is compared without its port: "api:8000" was accepted and matched no
    request, so every one behind that proxy was a 400."""
    with pytest.raises(ValidationError) as refused:
        Settings(INERTIA_ID_ALLOWED_HOSTS=f"ops.example.org,{entry}")
    (line,) = setting_problems(refused.value)
    assert line.startswith("INERTIA_ID_ALLOWED_HOSTS=")
    assert f"{entry!r} is not a host name" in line and f"e.g. {bare!r}" in line
    accepted = Settings(INERTIA_ID_ALLOWED_HOSTS=f"ops.example.org,{bare}")
    assert bare in accepted.resolved_allowed_hosts


@pytest.mark.parametrize(
    ("interval", "timeout"), [("60", "60"), ("90", "60"), ("5", "4.5"), ("59", "60"), ("31", "60")]
)
def test_a_heartbeat_interval_over_half_the_timeout_is_refused(interval: str, timeout: str) -> None:
    """A job beating every 90 s with a reaper timeout of 60 s is reaped while it runs, and
    one beating every 59 s was reaped after a single late or lost beat: at least two beats
    a timeout."""
    with pytest.raises(ValidationError) as refused:
        Settings(INERTIA_ID_HEARTBEAT_INTERVAL_S=interval, INERTIA_ID_HEARTBEAT_TIMEOUT_S=timeout)
    (line,) = setting_problems(refused.value)
    assert line.startswith(
        f"INERTIA_ID_HEARTBEAT_INTERVAL_S={float(interval):g} must be at most half "
        f"INERTIA_ID_HEARTBEAT_TIMEOUT_S={float(timeout):g} (at most {float(timeout) / 2:g} s)"
    )
    for accepted_interval, accepted_timeout in (("30", "60"), ("0.5", "3"), ("1.5", "3")):
        accepted = Settings(
            INERTIA_ID_HEARTBEAT_INTERVAL_S=accepted_interval,
            INERTIA_ID_HEARTBEAT_TIMEOUT_S=accepted_timeout,
        )
        assert accepted.heartbeat_interval_s == float(accepted_interval)


BAD_ENV = {
    "INERTIA_ID_MAX_BODY_BYTES": "-5",
    "INERTIA_ID_HEARTBEAT_TIMEOUT_S": "-1",
}


def _refused_lines(command: list[str], tmp_path: Path, **env: str) -> list[str]:
    data = tmp_path / "data"
    done = subprocess.run(
        command,
        capture_output=True,
        text=True,
        env=clean_env(INERTIA_ID_DATA_DIR=str(data), **env),
        cwd=tmp_path,
        timeout=120,
    )
    assert done.returncode == 1, done.stderr
    assert "Traceback" not in done.stderr, done.stderr
    assert not data.exists()
    return done.stderr.strip().splitlines()


def _command(program: str) -> list[str]:
    if program == "inertia-id serve":
        # A free port: serve checks its port before its settings.
        serve = [sys.executable, "-m", "app.serve", "--workers", "0"]
        return [*serve, "--port", str(free_port()), "--data-dir", "data"]
    if program == "inertia-id worker":
        return [sys.executable, "-m", "celery", "-A", "worker.celery_app", "worker"]
    return [sys.executable, "-m", "uvicorn", "app.main:create_app", "--factory", "--port", "1"]


@pytest.mark.parametrize("program", ["inertia-id serve", "inertia-id worker", "inertia-id api"])
def test_every_entry_point_refuses_a_bad_setting_in_one_line(program: str, tmp_path: Path) -> None:
    """``inertia-id serve``, a worker and the API under uvicorn: one line per bad setting,
    naming the variable and its value, status 1, nothing created (the worker and the API
    ended with a pydantic traceback, serve started with these values)."""
    command = _command(program)
    lines = _refused_lines(command, tmp_path, **BAD_ENV)
    assert lines == [
        f"{program}: INERTIA_ID_MAX_BODY_BYTES='-5': Input should be greater than or equal to 1",
        f"{program}: INERTIA_ID_HEARTBEAT_TIMEOUT_S='-1': Input should be greater than 0",
    ]
    lines = _refused_lines(command, tmp_path, INERTIA_ID_HEARTBEAT_INTERVAL_S="59")
    assert lines == [
        f"{program}: INERTIA_ID_HEARTBEAT_INTERVAL_S=59 must be at most half "
        "INERTIA_ID_HEARTBEAT_TIMEOUT_S=60 (at most 30 s): with fewer than two heartbeats a "
        "timeout, one late or lost beat gets a running job reaped"
    ]


def _readme_settings_table() -> dict[str, tuple[str, str]]:
    """The README's table of numeric settings: each variable's default and range cells
    as written (a row may name several, ``A, B | 10, 30``: the defaults in that order)."""
    rows: dict[str, tuple[str, str]] = {}
    for line in (ROOT / "README.md").read_text(encoding="utf-8").splitlines():
        cells = [cell.strip() for cell in line.strip().strip("|").split("|")]
        if len(cells) != 3 or not cells[0].startswith("`INERTIA_ID_"):
            continue
        names = [name.strip().strip("`") for name in cells[0].split(",")]
        defaults = [value.strip() for value in cells[1].split(",")]
        assert len(names) == len(defaults), f"README row {line!r}: names and defaults differ"
        for name, default in zip(names, defaults, strict=True):
            rows[name] = (default, cells[2])
    return rows


def test_the_readme_states_every_setting_and_each_numeric_ones_default_and_bound() -> None:
    """A new contributor follows the README: every setting of ``service/config.py`` is
    named there, and each numeric one sits in its table with the default the code uses
    and its lower bound (the request-head limits and the data folder were missing)."""
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    table = _readme_settings_table()
    problems = []
    for info in Settings.model_fields.values():
        name = str(info.alias)
        if name not in readme:
            problems.append(f"{name} is not in README.md")
        if info.annotation not in (int, float):
            continue
        if name not in table:
            problems.append(f"{name} is not in README.md's table of numeric settings")
            continue
        default, bound = table[name]
        if float(default) != info.default:
            problems.append(f"README gives {name} the default {default}, the code {info.default:g}")
        for rule in info.metadata:
            kind = type(rule).__name__
            if kind in ("Ge", "Gt"):
                limit = getattr(rule, kind.lower())
                sign = "≥" if kind == "Ge" else ">"
                if f"{sign} {limit:g}" not in bound and f"{limit:g}.." not in bound:
                    problems.append(
                        f"README gives {name} the range {bound!r}, the code {sign} {limit:g}"
                    )
            elif kind == "Le" and not name.endswith("_S"):
                # Every duration's ceiling is the one year the text above the table states.
                if f"..{rule.le:g}" not in bound and f"≤ {rule.le:g}" not in bound:
                    problems.append(
                        f"README gives {name} the range {bound!r}, the code ≤ {rule.le:g}"
                    )
    assert not problems, "\n".join(problems)
