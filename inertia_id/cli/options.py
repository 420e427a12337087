"""What the ``inertia-id`` commands share: options, parsing, output and error handling.

Importing this module (and every command module) loads click and nothing of the core:
``inertia-id --help`` lists the commands without importing numpy, pydantic or numba.
Choices that the core defines (presets, kinds, metrics, noises) are read the first time
click needs them (:class:`LazyChoice`); the core itself is imported inside the commands.
"""

from __future__ import annotations

import functools
import json
import math
import os
import re
import sys
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any, BinaryIO, TypeVar

import click

from ..checks import (
    MAX_SEED,
    DuplicateKeyError,
    finite_or_none,
    loads_unique_keys,
    parse_decimal,
    parse_whole,
)
from ..deadline import TIME_LIMIT_MIN_S
from ..errors import InputError
from ..pipelines import PAPER_SEQUENCE
from ..wording import counted

if TYPE_CHECKING:
    from ..physics.scenario import Scenario

F = TypeVar("F", bound=Callable[..., Any])

#: Most bytes a scenario file (``--scenario``) or a sequence file (``--sequence``) may
#: hold; past it the file is refused by its size, unread (a pipe, one byte past it). The
#: presets' JSON is 3 KB indented, and a 136-step sequence (the longest series the
#: service trains on) of 24 thrusters 24 KB: a megabyte is a wrong file, not a scenario.
MAX_SCENARIO_BYTES = 1_000_000
MAX_SEQUENCE_BYTES = 1_000_000


class LazyChoice(click.Choice[str]):
    """A :class:`click.Choice` whose choices come from the core when first needed.

    :param load: returns the choices; called once, when click validates a value. A
        command's help does not call it (loading the core's lists imports the classifier
        registry or the search package: seconds); the option's help text says the choices
        in words, and its metavar is the option's name.
    :param in_help: list the choices in the help all the same (a cheap ``load``).
    """

    def __init__(
        self,
        load: Callable[[], Sequence[str]],
        case_sensitive: bool = True,
        *,
        in_help: bool = False,
    ) -> None:
        self._load = load
        self._in_help = in_help
        self._loaded: tuple[str, ...] | None = None
        self.case_sensitive = case_sensitive

    @property
    def choices(self) -> tuple[str, ...]:
        if self._loaded is None:
            self._loaded = tuple(self._load())
        return self._loaded

    @choices.setter
    def choices(self, value: Sequence[str]) -> None:
        self._loaded = tuple(value)

    def get_metavar(self, param: click.Parameter, ctx: click.Context) -> str | None:
        if self._loaded is None and not self._in_help:
            return (param.name or "choice").upper()
        return super().get_metavar(param, ctx)


class IntRange(click.IntRange):
    """:class:`click.IntRange` of whole numbers written in ASCII digits: click reads with
    ``int``, which takes ``1_0`` as 10 and other scripts' digits."""

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> Any:
        if isinstance(value, str):
            try:
                parse_whole(value)
            except ValueError as exc:
                self.fail(str(exc), param, ctx)
        return super().convert(value, param, ctx)


class FloatRange(click.FloatRange):
    """:class:`click.FloatRange` of numbers written as a person writes them: click reads
    with ``float``, which takes ``1_0`` as 10 and other scripts' digits. ``inf`` and
    ``nan`` pass, as before: each command names them in its own words."""

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> Any:
        if isinstance(value, str):
            try:
                parse_decimal(value, non_finite=True)
            except ValueError as exc:
                self.fail(str(exc), param, ctx)
        return super().convert(value, param, ctx)


def friendly_errors(func: F) -> F:
    """Turn the caller's faults (the core's InputError, pydantic's validation errors, a
    file that cannot be read) into one-line CLI errors; anything else is a defect and
    keeps its traceback."""

    @functools.wraps(func)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        try:
            return func(*args, **kwargs)
        except OSError as exc:
            raise click.ClickException(str(exc)) from None
        except MemoryError:
            raise click.ClickException(
                "out of memory: the sizes asked for (realisations -n, test series, "
                "sequence length, flights) need more than this machine holds; ask for fewer"
            ) from None
        except UnicodeDecodeError as exc:
            # A binary file where text (JSON, CSV) was expected.
            raise click.ClickException(
                f"a file given is not UTF-8 text (byte {exc.object[exc.start : exc.end]!r} "
                f"at position {exc.start}): give a JSON or CSV file"
            ) from None
        except ValueError as exc:
            from pydantic import ValidationError

            if isinstance(exc, ValidationError):
                raise click.ClickException(one_line(exc)) from None
            if isinstance(exc, InputError):
                raise click.ClickException(str(exc)) from None
            raise

    return wrapper  # type: ignore[return-value]


def one_line(exc: BaseException) -> str:
    """An error as one line: a validation error's rules and values, without pydantic's
    type codes and links; anything else with its whitespace folded."""
    from pydantic import ValidationError

    if isinstance(exc, ValidationError):
        return "; ".join(_error_text(e["loc"], str(e["msg"])) for e in exc.errors())
    return " ".join(str(exc).split())


def _error_text(loc: tuple[Any, ...], msg: str) -> str:
    msg = msg.removeprefix("Value error, ")
    return f"{'.'.join(str(part) for part in loc)}: {msg}" if loc else msg


def _presets() -> list[str]:
    from ..physics.presets import PRESETS

    return sorted(PRESETS)


def scenario_options(func: F) -> F:
    """``--preset`` / ``--scenario FILE``."""
    func = click.option(
        "--scenario",
        "scenario_path",
        type=click.Path(dir_okay=False),
        help="Scenario JSON file (overrides --preset).",
    )(func)
    func = click.option(
        "--preset",
        "preset_name",
        default="paper",
        show_default=True,
        type=LazyChoice(_presets, in_help=True),
        help="Built-in scenario.",
    )(func)
    return func


def load_scenario(preset_name: str, scenario_path: str | None) -> Scenario:
    """The scenario the options name. A thruster of it that gives no torque (a zero
    column of its torque matrix) is warned of on stderr, as ``inertia-id scenario`` and
    the API warn of it: allowed, but likely a mistake; every command that takes
    ``--scenario`` loads it here, once, and stdout (JSON, CSV) is left as it was."""
    from ..physics.scenario import idle_thruster_warning

    scenario = _read_scenario(preset_name, scenario_path)
    idle = idle_thruster_warning(scenario.torque_matrix)
    if idle is not None:
        click.echo(f"warning: {idle}", err=True)
    return scenario


def _read_scenario(preset_name: str, scenario_path: str | None) -> Scenario:
    if scenario_path is None:
        from ..physics.presets import preset

        return preset(preset_name)
    from ..checks import DuplicateKeyError, loads_unique_keys, read_text
    from ..physics.scenario import Scenario

    # Read outside the try: a file refused for its size or encoding says so, not "not JSON".
    text = read_text(
        scenario_path,
        "a scenario's JSON",
        limit=MAX_SCENARIO_BYTES,
        advice="is it a scenario (inertia-id scenario writes one)?",
        opening="{",
    )
    try:
        document = loads_unique_keys(text)
    except DuplicateKeyError as exc:
        raise InputError(f"scenario {scenario_path!r} has a {exc}") from None
    except (ValueError, RecursionError) as exc:
        raise InputError(f"scenario {scenario_path!r} is not JSON: {exc}") from None
    return Scenario.model_validate(document)


def parse_sequence(text: str, scenario: Scenario | None = None) -> list[list[int]]:
    """A sequence from ``"4,4,4,0,0,0;0,0,0,4,4,4"`` (rows separated by ';'), a JSON
    list of rows, or a path to a file holding either (a named pipe too), or a command
    plan's JSON: on ``scenario``, the plan's commands (:func:`_plan_levels`)."""
    source = text
    # Any file but a folder: a named pipe, /dev/stdin or a process substitution
    # (<(cat seq.json), /dev/fd/63) too, as a flight team pipes files (isfile took
    # them for sequence text).
    from_file = os.path.exists(text) and not os.path.isdir(text)
    if from_file:
        from ..checks import read_text

        source = read_text(
            text,
            "a sequence: a JSON list of rows",
            limit=MAX_SEQUENCE_BYTES,
            advice="is it a sequence (rows of level indices)?",
        )
    source = source.strip()
    parts = source.removesuffix(";").split(";")
    empty = [i + 1 for i, row in enumerate(parts) if not row.strip()]
    if not source.startswith("[") and empty and len(parts) > 1:
        # An empty step is a typo or a coast meant: refuse it rather than drop it, which
        # would shift every later step's time.
        raise InputError(
            f"sequence {text!r}: step {empty[0]} is empty (a coasting step is written as "
            "zeros, e.g. '0,0,0,0,0,0')"
        )
    try:
        if source.startswith(("[", "{")):
            rows = loads_unique_keys(source)
        else:
            rows = [[parse_whole(v) for v in row.split(",")] for row in parts if row.strip()]
    except DuplicateKeyError as exc:
        raise InputError(f"sequence {text!r} has a {exc}") from None
    except (ValueError, RecursionError):
        # A path that names nothing (a typo, a file not yet written) is read as sequence
        # text: one that reads as a path (a name with a folder or an extension) is said
        # to be no file too, and a folder to be one.
        if os.path.isdir(text):
            missing = "a folder, not a file, and "  # (was said to be "no file by that name")
        elif not from_file and (os.sep in text or re.search(r"\.[A-Za-z]\w*$", text)):
            missing = "no file by that name, and "
        else:
            missing = ""
        raise InputError(
            f"sequence {text!r} is {missing}not rows of level indices like "
            "'4,4,4,0,0,0;0,0,0,4,4,4' or a JSON list of rows"
        ) from None
    if isinstance(rows, dict):
        document = rows
        rows = _sequence_in(document, text)
        if scenario is not None:
            rows = _plan_levels(document, rows, scenario, text)
    if not isinstance(rows, list) or not rows:
        raise InputError(f"sequence {text!r} holds no steps")
    refuse_decimal_levels(rows, text)
    return rows


def refuse_decimal_levels(rows: list[Any], text: str) -> None:
    """A level written as a decimal number in JSON (``1e0``, ``1.0``) is an
    :class:`InputError` naming it, as the service's sequences refuse it (the API's
    ``sequence`` and a job's, JSON integers only). The core's check takes a whole float,
    which a Python caller passes on purpose; typed into a file it is a slip (a level
    computed, or a duty meant), and the command line took it as the level."""
    steps = rows if rows and isinstance(rows[0], list) else [rows]
    for step, row in enumerate(steps):
        for thruster, level in enumerate(row if isinstance(row, list) else []):
            if isinstance(level, float):
                whole = f"write {int(level)}" if level.is_integer() else "e.g. 1"
                raise InputError(
                    f"sequence {text!r}: step {step + 1}, thruster {thruster + 1} is "
                    f"{level!r}, a decimal number; level indices are JSON integers ({whole})"
                )


def _sequence_in(document: Any, text: str) -> Any:
    """The sequence a JSON object holds under ``sequence``: a command plan's (``inertia-id
    plan`` writes one), so a plan kept is planned again, on another scenario too. A
    search's result holds many: it is refused naming the option that picks one."""
    if isinstance(document, dict) and isinstance(document.get("sequence"), list):
        return document["sequence"]
    if isinstance(document, dict) and ("front" in document or "best" in document):
        raise InputError(
            f"sequence {text!r} is a search's result, not one sequence: plan one of its "
            f"members with `inertia-id plan --search {text} --member N` (0 is its best), "
            "or give the rows of front.members[N].sequence"
        )
    raise InputError(
        f"sequence {text!r} is a JSON object with no 'sequence' list: give rows of level "
        "indices like '4,4,4,0,0,0;0,0,0,4,4,4', a JSON list of rows, or a command plan's JSON"
    )


def _is_number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)


def _plan_levels(document: dict, rows: Any, scenario: Scenario, text: str) -> Any:
    """A command plan's sequence on ``scenario``: at each step and thruster the
    scenario's level of the duty the plan commands (its ``steps[].duty``), on steps of
    the plan's duration. A plan's level indices name its own scenario's levels: read as
    another's (11 levels), full-duty firings were flown at 0.4 duty with no word.

    :raises InputError: the plan's steps last another time than the scenario's, or it
        commands a duty that is no level of the scenario (naming the step and thruster).
    """
    steps = document.get("steps")
    if not isinstance(steps, list):
        return rows  # no plan's steps ("steps": 5 was iterated): its sequence as given
    duties = [step.get("duty") if isinstance(step, dict) else None for step in steps]
    if not steps or not all(
        isinstance(row, list) and len(row) == scenario.n_thrusters and all(map(_is_number, row))
        for row in duties
    ):
        return rows  # no plan's commands (or not this scenario's thrusters): as given
    commanded: list[list[float]] = [row for row in duties if isinstance(row, list)]
    levels_given = [step.get("levels") for step in steps]
    if levels_given != rows:
        # Its sequence edited by hand (or its steps): which one is meant is not known.
        differs = next(
            (i for i, (a, b) in enumerate(zip(levels_given, rows, strict=False)) if a != b),
            min(len(levels_given), len(rows)),
        )
        raise InputError(
            f"sequence {text!r} is a command plan whose sequence and steps disagree (at step "
            f"{differs + 1}): edited by hand? Give the rows themselves (e.g. "
            "'4,4,4,0,0,0;0,0,0,4,4,4') or a plan as written"
        )
    planned_step = document.get("step_duration_s")
    step = scenario.timing.step_duration_s
    if (
        isinstance(planned_step, int | float)
        and _is_number(planned_step)
        and not math.isclose(planned_step, step, rel_tol=1e-12)
    ):
        raise InputError(
            f"sequence {text!r} is a command plan of {planned_step:g} s steps, and scenario "
            f"{scenario.name!r} steps {step:g} s: its on-times would change; plan its "
            f"sequence on a scenario of {planned_step:g} s steps"
        )
    from ..physics.scenario import LEVEL_ROUNDING

    levels = list(scenario.thrusters.levels)
    out = []
    for i, row in enumerate(commanded):
        out_row = []
        for j, duty in enumerate(row):
            # The plan writes each duty as its scenario's level; LEVEL_ROUNDING takes the
            # last bit of a level computed another way (0.30000000000000004 for 0.3).
            match = [k for k, level in enumerate(levels) if abs(level - duty) <= LEVEL_ROUNDING]
            if not match:
                raise InputError(
                    f"sequence {text!r} is a command plan whose step {i + 1}, thruster "
                    f"{j + 1} fires at duty {duty:g}, which is no duty level of scenario "
                    f"{scenario.name!r} (levels {', '.join(f'{v:g}' for v in levels)}): its "
                    "commands cannot be flown on it"
                )
            out_row.append(match[0])
        out.append(out_row)
    return out


#: The hand-designed sequence as the command line writes it.
DEFAULT_SEQUENCE_TEXT = ";".join(",".join(map(str, row)) for row in PAPER_SEQUENCE)


def sequence_option(
    default: str | None = None, *, required: bool = False, when_omitted: str = ""
) -> Callable[[F], F]:
    """``--sequence``; optional unless ``required`` (``when_omitted`` says what happens
    without it, in the help)."""
    help_text = (
        "Level indices per thruster, steps separated by ';' (e.g. '4,4,4,0,0,0;"
        "4,4,4,0,0,0'), a JSON list of rows, or a JSON file (a command plan's too)."
    )
    return click.option(
        "--sequence",
        "sequence_text",
        default=default,
        required=required,
        show_default=default is not None,
        help=f"{help_text} {when_omitted}".strip(),
    )


def realisations_option(help_text: str, default: int | None = 20) -> Callable[[F], F]:
    return click.option(
        "-n",
        "--realisations",
        default=default,
        show_default=default is not None,
        type=IntRange(1),
        help=help_text,
    )


def multiples_option(func: F) -> F:
    return click.option(
        "--multiples",
        default=None,
        help="Noise multiples of the training level, comma-separated, each 0 to 1000 "
        "[default: 1,2,...,8].",
    )(func)


def n_test_option(default: int) -> Callable[[F], F]:
    return click.option(
        "--n-test",
        default=default,
        show_default=True,
        type=IntRange(1),
        help="Test series per sweep point, spread evenly over the K candidates: "
        "n-test // K each (the rest is not drawn).",
    )


class _TimeLimitType(FloatRange):
    """A time limit as written; its floor is shown in ``--help`` as click shows a range,
    and refused by :func:`_time_limit` in the one sentence it says for inf and nan too
    (click's own check said "1e-09 is not in the range x>=1.0" instead)."""

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> Any:
        return FloatRange().convert(value, param, ctx)


def _time_limit(
    _context: click.Context, _parameter: click.Parameter, value: float | None
) -> float | None:
    """A usage error (exit status 2) for a time limit that is not a finite number of
    seconds of at least TIME_LIMIT_MIN_S."""
    if value is None or (math.isfinite(value) and value >= TIME_LIMIT_MIN_S):
        return value
    raise click.BadParameter(
        f"must be a finite number of seconds >= {TIME_LIMIT_MIN_S:g}, got {value!r}"
    )


def time_limit_option(help_text: str) -> Callable[[F], F]:
    """``--time-limit SECONDS`` (``time_limit_s``; none by default): ``search`` and
    ``train``, read alike; at least :data:`~inertia_id.deadline.TIME_LIMIT_MIN_S`, as a
    job's ``time_limit_s`` is."""
    return click.option(
        "--time-limit",
        "time_limit_s",
        default=None,
        # Not click's float, which reads 1_0 as 10.
        type=_TimeLimitType(TIME_LIMIT_MIN_S),
        metavar="SECONDS",
        callback=_time_limit,
        help=f"{help_text} At least {TIME_LIMIT_MIN_S:g} s (less is most likely "
        "milliseconds meant as seconds).",
    )


def seed_option(func: F) -> F:
    return click.option(
        "--seed",
        default=0,
        show_default=True,
        type=IntRange(0, MAX_SEED),
        help=f"Seed of every random draw (a whole number, 0 to {MAX_SEED}: the service's "
        "largest, so a run made here can be made again as a job).",
    )(func)


#: File name endings that promise a format other than JSON.
OTHER_FORMATS = (".csv", ".tsv", ".npz", ".npy", ".zip", ".xlsx", ".parquet", ".h5", ".pkl")


def _json_file_name(context: click.Context, param: click.Parameter, value: str | None) -> Any:
    """A JSON output named for another format (``res.csv``) is refused: JSON text was
    written into it, and a reader given the name failed or misread it."""
    if value is not None and value.lower().endswith(OTHER_FORMATS):
        raise click.BadParameter(f"this command writes JSON; name the file .json, got {value!r}")
    return value


def out_option(default: str | None, help_text: str, *, folder: bool = False) -> Callable[[F], F]:
    """``--out`` (or ``--out-dir``): where a command writes (a file: JSON)."""
    return click.option(
        "--out-dir" if folder else "--out",
        default=default,
        show_default=default is not None,
        type=click.Path(dir_okay=folder, file_okay=not folder),
        callback=None if folder else _json_file_name,
        help=help_text,
    )


def classifier_option(help_text: str) -> Callable[[F], F]:
    """``--classifier FILE``: a classifier document from ``train``."""
    return click.option(
        "--classifier",
        "classifier_path",
        required=True,
        type=click.Path(exists=True, dir_okay=False),
        help=help_text,
    )


def parse_multiples(text: str | None) -> list[float] | None:
    """``"1,2,4"`` -> ``[1.0, 2.0, 4.0]``; None stays None (the sweep's default)."""
    if text is None:
        return None
    items = text.split(",")
    if any(not v.strip() for v in items):
        raise InputError(
            f"--multiples {text!r} has an empty item; give numbers separated by commas"
        )
    try:
        return [parse_decimal(v) for v in items]
    except ValueError as exc:
        raise InputError(
            f"--multiples {text!r} is not a comma-separated list of numbers: {exc}"
        ) from None


def parse_radius(text: str) -> int | None:
    """A DTW band half-width, or None for 'none' (unconstrained)."""
    if text.strip().lower() in ("none", "full", "unconstrained"):
        return None
    try:
        value = parse_whole(text)
    except ValueError:
        value = -1
    if value < 0:
        raise InputError(f"--radius must be an integer >= 0 or 'none', got {text!r}")
    return value


def parse_pairs(pairs: Sequence[str], option: str, example: str) -> dict[str, Any]:
    """``("n_steps=1024", "gamma=0.9")`` -> ``{"n_steps": 1024, "gamma": 0.9}``."""
    params: dict[str, Any] = {}
    for pair in pairs:
        name, sep, value = pair.partition("=")
        if not sep or not name.strip():
            raise InputError(f"{option} takes NAME=VALUE (e.g. {example}), got {pair!r}")
        try:
            number = parse_decimal(value)
        except ValueError:
            raise InputError(
                f"{option} {name.strip()} must be a number written in ASCII digits with no "
                f"separator (e.g. {example}), got {value!r}"
            ) from None
        if name.strip() in params:
            raise InputError(f"{option} {name.strip()} is given twice; give it once")
        # An integer only when written as one, as JSON reads it: the API's ``1e0`` is a
        # float a whole-number setting refuses (NSGA-II's generations); here it was 1.
        try:
            params[name.strip()] = parse_whole(value)
        except ValueError:
            params[name.strip()] = number
    return params


def write_output(
    path: str | os.PathLike[str], data: str | bytes | Callable[[BinaryIO], None]
) -> None:
    """Write ``data`` to ``path`` whole or not at all (:func:`inertia_id.files.write_whole`);
    a failed write is one line naming the path: in place, it left a truncated file there
    and said only ``Error: [Errno 27] File too large``."""
    from ..files import NotWritten, write_whole

    try:
        write_whole(path, data)
    except NotWritten as exc:
        # Its words say what became of the path: a file is left as it was, a device or
        # pipe (written directly) may have taken part of it.
        raise click.ClickException(str(exc)) from None
    except OSError as exc:
        raise click.ClickException(f"could not write {os.fspath(path)}: {exc}") from None


def write_json(path: str | os.PathLike[str] | None, data: Any) -> None:
    """``data`` as indented JSON to ``path``, or to stdout for None or "-": strict JSON,
    a non-finite number written as null (``json.dumps`` would write NaN or Infinity,
    which strict parsers refuse)."""
    text = json.dumps(finite_or_none(data), indent=2, allow_nan=False)
    if path is None or str(path) == "-":
        click.echo(text)
    else:
        write_output(path, text + "\n")
        click.echo(f"wrote {path}", err=True)


#: A simulation's peak memory, in arrays of (candidates, realisations, samples, 3) float64
#: rates: the gyro noise drawn for every step, each step's true and measured rates and
#: applied torque, and those three joined over the steps. Measured: 8.4 times one such
#: array at 4000 realisations of the paper preset (peak resident size, numpy engine).
SIMULATION_ARRAYS = 9


def available_memory_bytes(meminfo: str = "/proc/meminfo") -> int | None:
    """The memory the kernel says a new process could take (MemAvailable), in bytes; None
    where that is not known (not Linux, or the file unreadable)."""
    try:
        with open(meminfo, encoding="ascii") as handle:
            for line in handle:
                name, _, value = line.partition(":")
                if name == "MemAvailable":
                    return int(value.split()[0]) * 1024  # stated in kB
    except (OSError, ValueError, IndexError):
        return None
    return None


def _bytes_text(n: float) -> str:
    for unit in ("bytes", "KB", "MB", "GB", "TB"):
        if n < 1000:
            return f"{n:.0f} {unit}" if unit == "bytes" else f"{n:.3g} {unit}"
        n /= 1000
    return f"{n:.3g} PB"


def refuse_past_memory(
    asked: str,
    *,
    candidates: int,
    realisations: int,
    samples: int,
    arrays: int = SIMULATION_ARRAYS,
) -> None:
    """Refuse sizes whose simulated rates would not fit in the memory available, before
    anything is allocated. Linux overcommits: numpy's MemoryError never came, and the
    process grew until the kernel killed it (``simulate -n 100000000`` reached 21 GB).

    :param asked: the options that set the size, as the user gave them (e.g. ``-n 5``).
    :param arrays: how many (candidates, realisations, samples, 3) float64 arrays are held
        at once.
    """
    need = candidates * realisations * samples * 3 * 8 * arrays
    available = available_memory_bytes()
    if available is not None and need > available:
        raise InputError(
            f"{asked}: {counted(candidates, 'candidate')} x "
            f"{counted(realisations, 'realisation')} x {counted(samples, 'sample')} x 3 axes "
            f"need about {_bytes_text(need)} ({counted(arrays, 'array')} of 8-byte "
            f"rates at once), more than the {_bytes_text(available)} of memory available; "
            "ask for fewer realisations"
        )


def progress_bar(total: int, desc: str, unit: str = "pt") -> Any:
    """A progress bar on stderr that disappears when done."""
    from tqdm import tqdm

    return tqdm(total=total, desc=desc, unit=unit, file=sys.stderr, leave=False)
