"""``ros2 run`` and ``ros2 pkg``: packages and executables through the ament index.

As in ros2cli, a package's executables are the files in ``<prefix>/lib/<package>/`` that
can be executed, where ``<prefix>`` is the package's entry in ``AMENT_PREFIX_PATH``; so
``ros2 run`` finds whatever workspace ``scripts/env.sh`` (or any ``setup.bash``) sourced.
"""

from __future__ import annotations

import argparse
import os
import shlex
import sys
from pathlib import Path

from ament_index_python.packages import (
    PackageNotFoundError,
    get_package_prefix,
    get_packages_with_prefixes,
)

from ._main import Commands, add_verbs, verb
from .errors import CliError, UsageError

RUN_USAGE = "usage: ros2 run [-h] [--prefix PREFIX] package_name executable_name [argv ...]"


def register(commands: Commands) -> None:
    run = commands.add_parser("run", help="Run a package specific executable",
                              usage=RUN_USAGE[len("usage: "):])
    run.add_argument("--prefix", help="Prefix command, which should go before the executable "
                     "(e.g. --prefix 'gdb -ex run --args')")
    run.add_argument("package_name")
    run.add_argument("executable_name")
    run.add_argument("argv", nargs=argparse.REMAINDER)
    verbs = add_verbs(commands, "pkg", "Various package related sub-commands")
    verb(verbs, "list", "Output a list of available packages", _list)
    p = verb(verbs, "prefix", "Output the prefix path of a package", _prefix)
    p.add_argument("package_name")
    p.add_argument("--share", action="store_true",
                   help="Show share directory for the package")
    p = verb(verbs, "executables", "Output a list of package specific executables",
             _executables)
    p.add_argument("package_name", nargs="?")
    p.add_argument("--full-path", action="store_true", help="Show the full path of each")


def prefix_of(package: str) -> Path:
    try:
        return Path(get_package_prefix(package))
    except (PackageNotFoundError, ValueError) as exc:
        raise CliError(f"Package '{package}' not found") from exc


def executables(package: str) -> list[Path]:
    folder = prefix_of(package) / "lib" / package
    if not folder.is_dir():
        return []
    return sorted(p for p in folder.iterdir()
                  if p.is_file() and os.access(p, os.X_OK) and not p.name.startswith("."))


def run_command(argv: list[str]) -> int:
    """``ros2 run [--prefix P] PKG EXE [args...]``: replaces this process with the program."""
    prefix: list[str] = []
    rest = list(argv)
    while rest and rest[0].startswith("-"):
        option = rest.pop(0)
        if option in ("-h", "--help"):
            print(RUN_USAGE)
            return 0
        if option == "--prefix" and rest:
            prefix = shlex.split(rest.pop(0))
        elif option.startswith("--prefix="):
            prefix = shlex.split(option[len("--prefix="):])
        else:
            raise UsageError(f"ros2 run: unrecognized option {option}; this install offers: "
                             "--prefix (a regular ROS 2 install (ros2cli) has the full "
                             "command line)")
    if len(rest) < 2:
        raise UsageError(f"ros2 run: package and executable names are required\n{RUN_USAGE}")
    package, name, args = rest[0], rest[1], rest[2:]
    found = [p for p in executables(package) if p.name == name]
    if not found:
        offered = ", ".join(p.name for p in executables(package)) or "none"
        raise CliError(f"No executable found: {name!r} in package {package!r} "
                       f"(it has: {offered})")
    command = [*prefix, str(found[0]), *args]
    sys.stdout.flush()
    try:
        os.execvp(command[0], command)  # replaces this process: its exit status is ours
    except OSError as exc:
        raise CliError(f"cannot run {shlex.join(command)}: {exc}") from exc
    raise AssertionError("unreachable: execvp returns only by raising")


def _list(_args: argparse.Namespace) -> int:
    for name in sorted(get_packages_with_prefixes()):
        print(name)
    return 0


def _prefix(args: argparse.Namespace) -> int:
    prefix = prefix_of(args.package_name)
    print(prefix / "share" / args.package_name if args.share else prefix)
    return 0


def _executables(args: argparse.Namespace) -> int:
    packages = [args.package_name] if args.package_name else sorted(get_packages_with_prefixes())
    for package in packages:
        for path in executables(package):
            print(path if args.full_path else f"{package} {path.name}")
    return 0
