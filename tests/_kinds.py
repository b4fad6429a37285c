"""Test kinds: which tier each test belongs to, from its file name (and a few test names).

The root ``conftest.py`` marks every collected test with its kinds through
:func:`kinds_of`, so a new test file gets its tier from where it lives and how it is named,
without a marker of its own. ``pytest -m fast`` (``scripts/test.sh --fast``) is the tier to
run after an edit; CI runs them all.

The kinds, each a pytest marker (declared in pyproject.toml):

* ``sil``: software in the loop: runs the simulated humanoid (MuJoCo physics behind the
  emulated servo bus, with the robot's software) for simulated seconds, in lockstep or in
  real time. CPU-bound: minutes on two cores.
* ``browser``: drives debug_gui in a headless chromium (``scripts/setup_browser.sh``).
  Every test that uses the ``browser`` (or ``chromium_session``) fixture gets it, whatever
  its file is called.
* ``bench``: runs a benchmark of ``bench/`` briefly, to show it still runs and reports.
* ``docs``: runs the command lines of README.md and docs/ as written.
* ``process``: starts separate programs or DDS participants and waits for them
  (discovery, a readiness line, a reply): mostly waiting, seconds per test.
* ``root``: needs root (network namespaces, mounting a tmpfs); as another user it is
  skipped with its reason, and the summary counts how many ran (CI as root fails if any
  was skipped).
* ``fast``: none of the above: in one process, no waiting on other programs, no
  simulated seconds. A file is only fast because a row here says so.

Rows are ``(pattern, kind)``. A file's kind is that of the LAST file row whose ``fnmatch``
pattern matches its path relative to the repository (``tests/test_x.py``): general rows
first, exceptions after them. Rows with ``::`` match a test's node id
(``tests/test_x.py::test_name*``) and add their kind to that test. A test with any kind
but ``fast`` is not fast.
"""

from __future__ import annotations

from collections.abc import Iterable
from fnmatch import fnmatchcase

#: The kinds that take a tier out of the fast one, in the order the docs explain them.
SLOW_KINDS = ("sil", "browser", "bench", "docs", "process", "root")
KINDS = (*SLOW_KINDS, "fast")

#: File patterns (the last match wins) and node-id patterns (adding a kind).
KIND_PATTERNS: tuple[tuple[str, str], ...] = (
    # Package unit tests: in-process, on a TestHandle or ManualClock.
    ("ros2_ws/src/*/test/test_*.py", "fast"),
    # ... except the ones that start programs (or a renderer's subprocess).
    ("ros2_ws/src/debug_gui/test/test_components_model.py", "process"),
    ("ros2_ws/src/debug_gui/test/test_layout_security.py", "process"),
    ("ros2_ws/src/efficient_comm/test/test_testing.py", "process"),
    ("ros2_ws/src/efficient_comm/test/test_signals.py", "process"),
    ("ros2_ws/src/rf_bridge/test/test_ros1_types.py", "process"),
    ("ros2_ws/src/humanoid_sim/test/test_render.py", "process"),
    # Renders and encodes simulated seconds of video (and probes EGL in a subprocess).
    ("ros2_ws/src/humanoid_sim/test/test_match_video.py", "sil"),
    # Top-level suites: cross-package, separate processes unless a row says otherwise.
    ("tests/test_*.py", "process"),
    ("tests/test_*_sil.py", "sil"),
    ("tests/test_demo*.py", "sil"),
    # The demo's argument checks start no simulation (it refuses before), so they wait on a
    # program like any process test, beside the others; the three that play are sil.
    ("tests/test_demo_args.py", "process"),
    ("tests/test_demo_args.py::test_negative_coordinates_*", "sil"),
    ("tests/test_demo_args.py::test_the_seed_draws_the_start*", "sil"),
    ("tests/test_demo_args.py::test_the_demo_films_the_match_*", "sil"),
    # Likewise a refused namespace (the demo) and a refused --localization (the match).
    ("tests/test_demo_watchable.py", "process"),
    ("tests/test_demo_watchable.py::test_demo_robot_publishes_*", "sil"),
    ("tests/test_match_localization_sil.py", "process"),
    ("tests/test_match_localization_sil.py::test_each_robot_runs_the_localization_*", "sil"),
    ("tests/test_gui_*_browser.py", "browser"),
    ("tests/test_*bench_smoke.py", "bench"),
    ("tests/test_docs_commands.py", "docs"),
    ("tests/test_test_kinds.py", "fast"),
    ("tests/test_package_rules.py", "fast"),
    ("tests/test_owners.py", "fast"),
    ("tests/test_gui_world_model.py", "fast"),
    ("tests/test_team_clock_recorder.py", "fast"),
    ("ros2_ws/src/humanoid_sim/test/test_match_log.py::test_the_installed_command*",
     "process"),
    # Root only: network namespaces, a tmpfs of our own.
    ("tests/test_rf_bridge_team.py::test_team_link_over_lossy_limited_link*", "root"),
    ("tests/test_recorder_robustness.py::test_real_small_file_system*", "root"),
    ("tests/test_throttle_bench_smoke.py::*", "root"),
    # A benchmark of waits (discovery, the graph daemon's settling, ``ros2 topic hz`` and
    # ``echo`` listening): 126 s wall for 32 s of CPU, a quarter of a core. It waits beside
    # the other process tests instead of holding the cpu lane (see serial_group).
    ("tests/test_cli_bench_smoke.py::*", "process"),
    # Round trips to ROS 1 through the bridge: 20 s wall for 6.5 s of CPU, every queue as
    # deep as its burst (so load delays messages but loses none).
    ("tests/test_bridge_bench_smoke.py::*", "process"),
    ("tests/test_lockstep_netns.py::*", "root"),
)


def kinds_of(path: str, name: str = "", *, fixtures: Iterable[str] = ()) -> set[str]:
    """The kinds of a test: ``path`` relative to the repository (``/`` separators),
    ``name`` its name inside the file (``test_x[param]``), ``fixtures`` those it uses.

    Empty when no file row matches: the file needs a row (tests/test_test_kinds.py says
    which).
    """
    node_id = f"{path}::{name}"
    kinds: set[str] = set()
    file_kind: str | None = None
    for pattern, kind in KIND_PATTERNS:
        if "::" in pattern:
            if fnmatchcase(node_id, pattern):
                kinds.add(kind)
        elif fnmatchcase(path, pattern):
            file_kind = kind
    if file_kind is None:
        return set()
    kinds.add(file_kind)
    if {"browser", "chromium_session"} & set(fixtures):
        kinds.add("browser")
    if kinds & set(SLOW_KINDS):
        kinds.discard("fast")
    return kinds


#: Kinds whose tests share one pytest-xdist worker, one test at a time, when the suite runs
#: in parallel (``scripts/test.sh``: ``-n`` with ``--dist loadgroup``). Simulations and
#: benchmarks each keep a core busy, and two of them side by side on a two-core machine
#: only slow each other (and every waiting test) down; docs commands start the programs
#: the docs name, as written, so two blocks could want the same thing at once. Every other
#: test mostly waits (discovery, a reply, a browser) and runs beside the others.
SERIAL_GROUPS = {"sil": "cpu", "bench": "cpu", "docs": "docs"}


def serial_group(kinds: Iterable[str]) -> str | None:
    """The xdist group of a test of these kinds (None: it may run beside any other).

    A benchmark that a row also makes a ``process`` test mostly waits on other programs
    (it keeps no core busy), so it waits beside the others like one; a simulation does not.
    """
    kinds = set(kinds)
    if "process" in kinds:
        kinds.discard("bench")
    groups = sorted({SERIAL_GROUPS[k] for k in kinds if k in SERIAL_GROUPS})
    return groups[0] if groups else None
