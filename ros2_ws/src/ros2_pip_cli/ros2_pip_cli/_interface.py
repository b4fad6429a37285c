"""``ros2 interface list|package|show``, from the ament index the wheels and workspace hold.

Interface packages register their files under the ``rosidl_interfaces`` resource type
(``msg/String.msg``, ``srv/SetBool.srv`` ...); ``show`` prints the definition file and, as
ros2cli does, every nested type's definition indented by a tab (without its comments unless
``--all-comments``).
"""

from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path

from ament_index_python.packages import PackageNotFoundError, get_package_share_directory
from ament_index_python.resources import get_resource, get_resources

from ._main import Commands, add_verbs, verb
from .errors import CliError

_KINDS = (("msg", "Messages"), ("srv", "Services"), ("action", "Actions"))
_PRIMITIVES = {"bool", "byte", "char", "float32", "float64", "int8", "uint8", "int16",
               "uint16", "int32", "uint32", "int64", "uint64", "string", "wstring"}


def register(commands: Commands) -> None:
    verbs = add_verbs(commands, "interface", "Show information about ROS interfaces")
    p = verb(verbs, "list", "List all interface types available", _list)
    p.add_argument("-m", "--only-msgs", action="store_true", help="Print out only the messages")
    p.add_argument("-s", "--only-srvs", action="store_true", help="Print out only the services")
    p.add_argument("-a", "--only-actions", action="store_true",
                   help="Print out only the actions")
    p = verb(verbs, "package", "Output a list of available interface types within one package",
             _package)
    p.add_argument("package_name")
    p = verb(verbs, "packages", "Output a list of packages that provide interfaces", _packages)
    p = verb(verbs, "show", "Output the interface definition", _show)
    comments = p.add_mutually_exclusive_group()
    comments.add_argument("--all-comments", action="store_true",
                          help="Show all comments, including for nested interface definitions")
    comments.add_argument("--no-comments", action="store_true",
                          help="Show no comments or whitespace")
    p.add_argument("type", help="e.g. 'std_msgs/msg/String'; '-' reads it from stdin")


def interfaces(package: str) -> list[str]:
    """``msg/String``, ``srv/SetBool`` ... of one package, sorted."""
    try:
        content, _ = get_resource("rosidl_interfaces", package)
    except LookupError as exc:
        raise CliError(f"Unknown package '{package}'") from exc
    names = set()
    for line in content.splitlines():
        path = Path(line.strip())
        if path.suffix in (".msg", ".srv", ".action") and path.parent.name:
            names.add(f"{path.parent.as_posix()}/{path.stem}")
    return sorted(names)


def _list(args: argparse.Namespace) -> int:
    wanted = {"msg": args.only_msgs, "srv": args.only_srvs, "action": args.only_actions}
    everything = not any(wanted.values())
    packages = sorted(get_resources("rosidl_interfaces"))
    for kind, title in _KINDS:
        if not (everything or wanted[kind]):
            continue
        print(f"{title}:")
        for package in packages:
            for name in interfaces(package):
                if name.startswith(kind + "/"):
                    print(f"    {package}/{name}")
    return 0


def _package(args: argparse.Namespace) -> int:
    for name in interfaces(args.package_name):
        print(f"{args.package_name}/{name}")
    return 0


def _packages(_args: argparse.Namespace) -> int:
    for package in sorted(get_resources("rosidl_interfaces")):
        print(package)
    return 0


def definition_path(identifier: str) -> Path:
    parts = identifier.split("/")
    if len(parts) != 3 or not all(parts):
        raise CliError(f"Invalid name '{identifier}'. Expected three parts separated by '/'")
    package, kind, name = parts
    try:
        share = Path(get_package_share_directory(package))
    except (PackageNotFoundError, ValueError) as exc:
        raise CliError(f"Unknown package '{package}'") from exc
    path = share / kind / f"{name}.{kind}"
    if not path.is_file():
        raise CliError(f"Could not find the interface '{identifier}'")
    return path


def _nested(package: str, line: str) -> str | None:
    """The ``pkg/msg/Type`` a definition line's field refers to, if not a primitive."""
    code = line.split("#", 1)[0].strip()
    tokens = code.split()
    if len(tokens) < 2 or "=" in tokens[1] or code == "---":
        return None
    base = re.sub(r"(\[.*\]|<=\d+)$", "", tokens[0])
    base = re.sub(r"<=\d+$", "", base)
    if base in _PRIMITIVES:
        return None
    if "/" in base:
        pkg, _, name = base.rpartition("/")
        return f"{pkg.split('/')[0]}/msg/{name}"
    return f"{package}/msg/{base}"


def _show_lines(identifier: str, *, comments: bool, nested_comments: bool,
                indent: int) -> list[str]:
    package = identifier.split("/")[0]
    out: list[str] = []
    for raw in definition_path(identifier).read_text().splitlines():
        text = raw.rstrip()
        if not comments:
            code = text.split("#", 1)[0].rstrip() if not text.lstrip().startswith("#") else ""
            if not code.strip():
                if text.strip() != "---":
                    continue
            else:
                text = code
        out.append("\t" * indent + text if text else "")
        nested = _nested(package, text)
        if nested is not None:
            out += _show_lines(nested, comments=nested_comments,
                               nested_comments=nested_comments, indent=indent + 1)
    return out


def _show(args: argparse.Namespace) -> int:
    identifier = sys.stdin.readline().strip() if args.type == "-" else args.type
    if identifier.count("/") == 1:
        raise CliError(f"Invalid name '{identifier}'. Expected three parts separated by '/'")
    for line in _show_lines(identifier, comments=not args.no_comments,
                            nested_comments=args.all_comments, indent=0):
        print(line)
    return 0
