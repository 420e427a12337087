"""What importing the core costs: no torch, tslearn or stable-baselines3 until used.

Each check runs in a fresh interpreter, since this test session has imported them all.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from inertia_id import InertiaClassifier

HEAVY = ("torch", "tslearn", "stable_baselines3", "sklearn", "numba", "scipy", "pydantic")


def loaded_after(code: str) -> set[str]:
    """The HEAVY packages in sys.modules after running ``code`` in a fresh interpreter."""
    probe = (
        f"{code}\nimport sys, json\nprint(json.dumps([m for m in {HEAVY!r} if m in sys.modules]))"
    )
    done = subprocess.run(
        [sys.executable, "-c", probe], capture_output=True, text=True, check=True, timeout=120
    )
    return set(json.loads(done.stdout.strip().splitlines()[-1]))


def test_import_inertia_id_loads_none_of_the_heavy_packages() -> None:
    assert loaded_after("import inertia_id; inertia_id.__all__") == set()


def test_a_name_is_imported_when_first_used() -> None:
    loaded = loaded_after("from inertia_id import Scenario, simulate; Scenario.paper()")
    assert loaded == {"pydantic"}


def test_the_command_line_help_loads_no_science() -> None:
    code = (
        "from inertia_id.cli import main\ntry:\n    main(['--help'])\nexcept SystemExit:\n    pass"
    )
    assert loaded_after(code) == set()


# (serve hands its arguments, --help included, to the server's own parser in app.serve.)
@pytest.mark.parametrize(
    "command", ["identify", "paper", "scenario", "search", "simulate", "sweep", "train"]
)
def test_every_commands_help_loads_no_science(command: str) -> None:
    # The choices of --kind, --method or --metric come from the core: the help names them
    # in words and never loads the registry or the search package for them.
    code = (
        "from inertia_id.cli import main\ntry:\n"
        f"    main([{command!r}, '--help'])\nexcept SystemExit:\n    pass"
    )
    assert not loaded_after(code) & {"torch", "tslearn", "stable_baselines3", "sklearn", "numba"}


def test_paper_help_does_not_mark_the_sequence_required() -> None:
    done = subprocess.run(
        [sys.executable, "-m", "inertia_id.cli", "paper", "--help"],
        capture_output=True,
        text=True,
        check=True,
        timeout=120,
    )
    sequence = done.stdout.split("\n  --sequence", 1)[1].split("\n  --", 1)[0]
    assert "required" not in sequence and "Optional" in sequence


def test_the_search_package_loads_no_torch() -> None:
    loaded = loaded_after("import inertia_id.search; from inertia_id.search import ppo_search")
    assert not loaded & {"torch", "stable_baselines3", "tslearn"}
    assert "torch" in loaded_after("from inertia_id.search import SearchCallback")


def test_a_loaded_clustering_classifies_without_tslearn(
    euclidean_classifier: InertiaClassifier, tmp_path: Path
) -> None:
    for metric in ("euclidean", "dtw"):
        model = InertiaClassifier.from_json(euclidean_classifier.to_json())
        model.set_params(metric=metric)
        path = tmp_path / f"{metric}.json"
        model.save(path)
        code = (
            "import numpy as np\n"
            "from inertia_id import load_classifier\n"
            f"model = load_classifier({str(path)!r})\n"
            "print(model.predict(np.zeros((2, 80, 3))).tolist())"
        )
        loaded = loaded_after(code)
        assert "tslearn" not in loaded and "torch" not in loaded, metric


def test_warm_up_compiles_the_kernels_every_transform_calls() -> None:
    """In a fresh process: after ``inertia_id.warm_up()`` no transform compiles anything."""
    code = (
        "import json, inertia_id\n"
        "inertia_id.warm_up()\n"
        "from inertia_id.classifiers import dtw, minirocket\n"
        "from inertia_id.physics import _rk4\n"
        "kernels = [dtw._cdist, dtw._cdist_soft_dtw_normalized, minirocket._transform,\n"
        "           _rk4.integrate]\n"
        "warmed = [len(k.signatures) for k in kernels]\n"
        # A simulation, as a job or a plan runs one, compiles no version of its own.
        "import numpy as np\n"
        "from inertia_id import Scenario, Simulator\n"
        "simulator = Simulator(Scenario.paper(), 2)\n"
        "noise = simulator.draw_noise(np.random.default_rng(0), 2)\n"
        "simulator.run(np.array([[4, 4, 4, 0, 0, 0]] * 2), noise)\n"
        "print(json.dumps([warmed, len(_rk4.integrate.signatures)]))"
    )
    done = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=300
    )
    warmed, after = json.loads(done.stdout.strip().splitlines()[-1])
    assert all(warmed) and after == warmed[-1]


def test_the_api_process_starts_without_the_heavy_packages_and_warms_up_without_torch(
    tmp_path: Path,
) -> None:
    settings = (
        "from service.config import Settings\n"
        f"settings = Settings(INERTIA_ID_DATA_DIR={str(tmp_path)!r}, INERTIA_ID_API_KEY='k' * 32)\n"
    )
    # Serving /health needs none of the science: the app answers before the core loads.
    started = loaded_after(settings + "from app.main import create_app\ncreate_app(settings)")
    assert not started & {"torch", "tslearn", "stable_baselines3", "sklearn", "numba"}
    # The background warm-up loads every classifier kind and compiles the kernels, and
    # still no torch: that is the workers' business (PPO).
    warmed = loaded_after(
        settings + "from app.main import create_app, _warm_up_core\n"
        "create_app(settings)\n_warm_up_core()"
    )
    assert {"sklearn", "numba"} <= warmed
    assert not warmed & {"torch", "stable_baselines3", "tslearn"}
