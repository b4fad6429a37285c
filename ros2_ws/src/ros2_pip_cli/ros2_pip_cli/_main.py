"""The command line: ``ros2 COMMAND VERB ...``, and the error for what is not offered.

Each command module has ``register(commands)``, adding its parser and verbs; every verb's
parser sets ``run`` to a function of the parsed arguments returning an exit code.
"""

from __future__ import annotations

import argparse
import importlib
import os
import re
import sys
from collections.abc import Callable, Sequence
from typing import Any, NoReturn

from ._timing import ANNOUNCE_S
from .errors import CliError, UsageError

HINT = "a regular ROS 2 install (ros2cli) has the full command line"


class Parser(argparse.ArgumentParser):
    """An ArgumentParser whose errors list what this install offers instead of exiting."""

    def error(self, message: str) -> NoReturn:
        raise UsageError(offered_message(self, message))


def offered_message(parser: argparse.ArgumentParser, message: str) -> str:
    """``ros2 topic: 'bar' is not offered by this install; it offers: list, ...``."""
    match = re.search(r"invalid choice: '([^']*)'", message)
    if match:
        message = f"'{match.group(1)}' is not offered by this install"
    offered = _offered(parser)
    return (f"{parser.prog}: {message}" + (f"; it offers: {offered}" if offered else "")
            + f" ({HINT})")


def _offered(parser: argparse.ArgumentParser) -> str:
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            return ", ".join(action.choices)
    options = [o for a in parser._actions for o in a.option_strings if o.startswith("--")]
    return ", ".join(options)


Commands = Any  # argparse's _SubParsersAction, which is private


def add_verbs(commands: Commands, name: str, help_text: str) -> Commands:
    """A command's parser with its verbs as sub-parsers (``dest='verb'``)."""
    parser = commands.add_parser(name, help=help_text, description=help_text)
    return parser.add_subparsers(dest="verb", required=True, metavar="VERB",
                                 parser_class=Parser)


def verb(verbs: Commands, name: str, help_text: str,
         run: Callable[[argparse.Namespace], int]) -> argparse.ArgumentParser:
    parser: argparse.ArgumentParser = verbs.add_parser(name, help=help_text,
                                                       description=help_text)
    parser.set_defaults(run=run, parser=parser)
    return parser


def add_spin_time(parser: argparse.ArgumentParser) -> None:
    """ros2cli's ``--spin-time`` (without its daemon): listen at least this long."""
    parser.add_argument("--spin-time", type=float, default=ANNOUNCE_S, metavar="SPIN_TIME",
                        help="Listen at least this many seconds for discovery, then until the "
                             f"graph is stable (default: {ANNOUNCE_S}, one announcement period "
                             "of Fast DDS)")


def add_list_verb(verbs: Any, noun: str, handler: Callable[[argparse.Namespace], int]) -> None:
    """``ros2 topic list`` and ``ros2 service list`` take the same options (ros2cli's
    ``-t``, ``-c``, ``--include-hidden-<noun>s``); ``handler`` reads them as
    ``show_types``, ``count`` and ``include_hidden``."""
    p = verb(verbs, "list", f"Output a list of available {noun}s", handler)
    add_spin_time(p)
    p.add_argument("-t", "--show-types", action="store_true",
                   help=f"Additionally show the {noun} type")
    p.add_argument("-c", f"--count-{noun}s", dest="count", action="store_true",
                   help=f"Only display the number of {noun}s discovered")
    p.add_argument(f"--include-hidden-{noun}s", dest="include_hidden", action="store_true",
                   help=f"Consider hidden {noun}s as well")


def print_names(names: list[tuple[str, list[str]]], args: argparse.Namespace) -> int:
    """What a list verb prints: the count, or a line a name (with its types for ``-t``)."""
    if args.count:
        print(len(names))
        return 0
    for name, types in names:
        print(f"{name} [{', '.join(types)}]" if args.show_types else name)
    return 0


#: The verbs that take ros2cli's ``--no-daemon`` (those of ros2cli that do; verbs this
#: install lacks are skipped). Only the graph verbs use the daemon (see _view); the others
#: accept the option so that scripts written for ros2cli run.
NO_DAEMON_VERBS = {
    "topic": ("list", "info", "type", "echo", "find"),
    "node": ("list", "info"),
    "service": ("list", "type", "find", "info", "echo"),
    "param": ("list", "get", "set", "dump", "load", "describe", "delete"),
    "component": ("list", "load", "unload"),
}


def _add_no_daemon(commands: Commands) -> None:
    for command, names in NO_DAEMON_VERBS.items():
        verbs = _subparsers(commands.choices[command]) if command in commands.choices else None
        for name in names:
            if verbs is not None and name in verbs.choices:
                verbs.choices[name].add_argument(
                    "--no-daemon", action="store_true",
                    help="Do not spawn nor use an already running daemon")


def _subparsers(parser: argparse.ArgumentParser) -> Commands | None:
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            return action
    return None


#: The commands and the module of each, imported only when its command is used: a graph
#: verb answered by the daemon then loads what it needs, not every command's dependencies
#: (``bag`` alone imports the recorder), which would be most of its run time.
COMMAND_MODULES = {"bag": "_bag", "component": "_component", "daemon": "_daemon",
                   "interface": "_interface", "node": "_node", "param": "_param",
                   "pkg": "_pkg", "service": "_service", "topic": "_topic"}


def build_parser(command: str | None = None) -> Parser:
    """The parser of ``command`` only, if it is one of :data:`COMMAND_MODULES`; else of
    all commands (for help and for the error that lists what is offered)."""
    parser = Parser(prog="ros2", description=(
        "The ros2 command of the pip install of ROS 2: the verbs most used, with ros2cli's "
        f"arguments and output formats; {HINT}."))
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND",
                                     parser_class=Parser)
    names = [command] if command in COMMAND_MODULES else list(COMMAND_MODULES)
    for name in names:
        importlib.import_module(f".{COMMAND_MODULES[name]}", __package__).register(commands)
    _add_no_daemon(commands)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run one ``ros2`` command; returns its exit status (errors: one line on stderr)."""
    args_in = list(sys.argv[1:] if argv is None else argv)
    try:
        if args_in[:1] == ["run"]:
            from ._pkg import run_command

            return run_command(args_in[1:])
        args, unknown = build_parser(args_in[0] if args_in else None).parse_known_args(
            args_in)
        if unknown:
            raise UsageError(offered_message(
                args.parser, f"unrecognized arguments: {' '.join(unknown)}"))
        status: int = args.run(args)
        return status
    except UsageError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except CliError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        return 0
    except BrokenPipeError:  # `ros2 topic echo /x | head`
        sys.stderr.close()
        return 0
    except Exception as exc:  # a bug or an rclpy failure: still one line, with its kind
        if os.environ.get("ROS2_PIP_CLI_TRACEBACK"):
            raise
        print(f"error: {exc!r} (ROS2_PIP_CLI_TRACEBACK=1 shows where)", file=sys.stderr)
        return 1
