"""``ros2 param list|get|set|delete|dump|load|describe``, through the nodes' parameter services.

Every rclpy (and rclcpp) node offers the ``rcl_interfaces`` parameter services, so these
work against any node; the printed lines are ros2cli's (``Integer value is: 5``).
"""

from __future__ import annotations

import argparse
import re
import sys
from typing import Any

import yaml
from rcl_interfaces.msg import Parameter as ParameterMsg
from rcl_interfaces.msg import ParameterType
from rcl_interfaces.srv import DescribeParameters, GetParameters, ListParameters, SetParameters
from rclpy.parameter import Parameter, parameter_dict_from_yaml_file, parameter_value_to_python

from ._graph import WAIT_S, CliNode, absolute, cli_node
from ._main import Commands, add_spin_time, add_verbs, verb
from .errors import CliError

_LABELS = {
    ParameterType.PARAMETER_BOOL: ("Boolean value is:", "boolean"),
    ParameterType.PARAMETER_INTEGER: ("Integer value is:", "integer"),
    ParameterType.PARAMETER_DOUBLE: ("Double value is:", "double"),
    ParameterType.PARAMETER_STRING: ("String value is:", "string"),
    ParameterType.PARAMETER_BYTE_ARRAY: ("Byte values are:", "byte array"),
    ParameterType.PARAMETER_BOOL_ARRAY: ("Boolean values are:", "boolean array"),
    ParameterType.PARAMETER_INTEGER_ARRAY: ("Integer values are:", "integer array"),
    ParameterType.PARAMETER_DOUBLE_ARRAY: ("Double values are:", "double array"),
    ParameterType.PARAMETER_STRING_ARRAY: ("String values are:", "string array"),
    ParameterType.PARAMETER_NOT_SET: ("Parameter not set.", "not set"),
}


def register(commands: Commands) -> None:
    verbs = add_verbs(commands, "param", "Various param related sub-commands")
    p = verb(verbs, "list", "Output a list of available parameters", _list)
    add_spin_time(p)
    p.add_argument("node_name", nargs="?", help="Name of the ROS node")
    p.add_argument("--param-type", action="store_true", help="Print parameter types with "
                   "parameter names")
    p.add_argument("--filter", help="Only list parameters whose names match this regex")
    p = verb(verbs, "get", "Get parameter", _get)
    p.add_argument("node_name")
    p.add_argument("parameter_name")
    p.add_argument("--hide-type", action="store_true", help="Hide the type information")
    p = verb(verbs, "set", "Set parameter", _set)
    p.add_argument("node_name")
    p.add_argument("parameter_name")
    p.add_argument("value", help="Value of the parameter (YAML: 5, 1.5, true, '[1, 2]', text)")
    p = verb(verbs, "delete", "Delete parameter", _delete)
    p.add_argument("node_name")
    p.add_argument("parameter_name")
    p.add_argument("--include-hidden-nodes", action="store_true",
                   help="accepted for compatibility: any node can be named")
    p.add_argument("--timeout", type=float, default=WAIT_S, metavar="N",
                   help=f"Wait for N seconds until the node becomes available (default: "
                        f"{WAIT_S:g}; without a daemon, discovery takes longer than ros2cli's "
                        "1 s)")
    p = verb(verbs, "dump", "Show all of the parameters of a node in a YAML file format", _dump)
    p.add_argument("node_name")
    p = verb(verbs, "load", "Load parameter file for a node", _load)
    p.add_argument("node_name")
    p.add_argument("parameter_file", help="Parameter file (the params-file layout)")
    p.add_argument("--no-use-wildcard", action="store_true",
                   help="Do not load parameters in the '/**' namespace into the node")
    p = verb(verbs, "describe", "Show descriptive information about declared parameters",
             _describe)
    p.add_argument("node_name")
    p.add_argument("parameter_names", nargs="+")


def _names(cli: CliNode, node: str, prefixes: list[str] | None = None) -> list[str]:
    request = ListParameters.Request(prefixes=prefixes or [], depth=0)
    return sorted(cli.call(ListParameters, f"{node}/list_parameters", request).result.names)


def _values(cli: CliNode, node: str, names: list[str]) -> list[Any]:
    response = cli.call(GetParameters, f"{node}/get_parameters",
                        GetParameters.Request(names=names))
    return list(response.values)


def _list(args: argparse.Namespace) -> int:
    with cli_node() as cli:
        if args.node_name:
            cli.require_node(args.node_name)
            nodes = [absolute(args.node_name)]
        else:
            cli.settle(min_s=args.spin_time)
            nodes = cli.node_names()
        pattern = re.compile(args.filter) if args.filter else None
        for node in nodes:
            try:
                names = _names(cli, node)
            except CliError:
                print(f"Wait for service timed out waiting for parameter services for node "
                      f"{node}")
                continue
            if pattern is not None:
                names = [n for n in names if pattern.match(n)]
            if not args.node_name and names:
                print(f"{node}:")
            types: dict[str, str] = {}
            if args.param_type and names:
                described = cli.call(DescribeParameters, f"{node}/describe_parameters",
                                     DescribeParameters.Request(names=names))
                types = {d.name: _LABELS[d.type][1] for d in described.descriptors}
            for name in names:
                print(f"  {name} (type: {types[name]})" if name in types else f"  {name}")
    return 0


def _get(args: argparse.Namespace) -> int:
    with cli_node() as cli:
        cli.require_node(args.node_name)
        values = _values(cli, absolute(args.node_name), [args.parameter_name])
    if not values:
        raise CliError("Parameter not set")
    value = values[0]
    if value.type not in _LABELS:
        raise CliError(f"Unknown parameter type '{value.type}'")
    label = _LABELS[value.type][0]
    python = _python(value) if value.type != ParameterType.PARAMETER_NOT_SET else None
    if args.hide_type:
        print(python)
    elif python is None:
        print(label)
    else:
        print(label, python)
    return 0


def _python(value: Any) -> Any:
    """A ParameterValue as YAML-friendly Python (arrays as lists, as ros2cli prints them)."""
    python = parameter_value_to_python(value)
    if hasattr(python, "tolist"):
        return python.tolist()
    if isinstance(python, (tuple, list)):
        return list(python)
    return python


def parameter_from_text(name: str, text: str) -> ParameterMsg:
    """``5`` an integer, ``1.5`` a double, ``true`` a bool, ``[1, 2]`` an array, else text."""
    try:
        value = yaml.safe_load(text)
    except yaml.YAMLError:
        value = text
    if value is None or isinstance(value, dict):
        value = text
    if isinstance(value, list) and len({type(v) for v in value}) > 1:
        if all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in value):
            value = [float(v) for v in value]
        else:
            value = text
    try:
        return Parameter(name, value=value).to_parameter_msg()
    except (TypeError, ValueError, AttributeError):
        return Parameter(name, value=text).to_parameter_msg()


def _set(args: argparse.Namespace) -> int:
    with cli_node() as cli:
        cli.require_node(args.node_name)
        request = SetParameters.Request(
            parameters=[parameter_from_text(args.parameter_name, args.value)])
        result = cli.call(SetParameters, f"{absolute(args.node_name)}/set_parameters",
                          request).results[0]
    if result.successful:
        print("Set parameter successful" + (f": {result.reason}" if result.reason else ""))
        return 0
    print("Setting parameter failed" + (f": {result.reason}" if result.reason else ""),
          file=sys.stderr)
    return 1


def _delete(args: argparse.Namespace) -> int:
    """ros2cli's ``param delete``: set the parameter to NOT_SET, which undeclares it (a
    statically typed parameter refuses, and the node's reason is printed)."""
    node = absolute(args.node_name)
    with cli_node() as cli:
        if not cli.wait_for(lambda: cli.has_node(node), timeout_s=args.timeout):
            raise CliError("Node not found")
        result = cli.call(SetParameters, f"{node}/set_parameters", SetParameters.Request(
            parameters=[ParameterMsg(name=args.parameter_name)])).results[0]
    reason = f": {result.reason}" if result.reason else ""
    if result.successful:
        print(f"Deleted parameter successfully{reason}")
        return 0
    print(f"Deleting parameter failed{reason}", file=sys.stderr)
    return 1


def _dump(args: argparse.Namespace) -> int:
    node = absolute(args.node_name)
    with cli_node() as cli:
        cli.require_node(node)
        names = _names(cli, node)
        values = _values(cli, node, names) if names else []
    params: dict[str, Any] = {}
    for name, value in zip(names, values, strict=False):
        python = _python(value)
        target = params
        *groups, leaf = name.split(".")
        for group in groups:  # ros2cli nests dotted names
            target = target.setdefault(group, {})
        target[leaf] = python
    print(yaml.dump({node: {"ros__parameters": params}}, default_flow_style=False))
    return 0


def _file_parameters(path: str, node: str, *, use_wildcard: bool) -> dict[str, Any]:
    """The parameters of a params file for ``node``, read by rclpy's own loader.

    As ``ros2 param load`` (rclpy's ``load_parameter_file``): ``/**`` first unless
    ``--no-use-wildcard``, then the node's own section, whose values win. The section may be
    spelled with or without the leading slash (``talker:``). A file with no section for the
    node loads all of its sections, as ros2cli does (a file dumped from one node loads into
    another)."""
    with open(path) as f:
        document = yaml.safe_load(f)
    if not isinstance(document, dict):
        raise CliError(f"{path}: not a parameter file (expected a dictionary of node names)")
    own = [key for key in document if isinstance(key, str) and key != "/**"
           and absolute(key) == node]
    return parameter_dict_from_yaml_file(path, use_wildcard, target_nodes=own or None)


def _load(args: argparse.Namespace) -> int:
    node = absolute(args.node_name)
    try:
        params = _file_parameters(args.parameter_file, node,
                                  use_wildcard=not args.no_use_wildcard)
    except FileNotFoundError as exc:
        raise CliError(f"no parameter file {args.parameter_file}") from exc
    except (RuntimeError, yaml.YAMLError, ValueError, TypeError, AttributeError) as exc:
        raise CliError(f"{args.parameter_file}: {str(exc).splitlines()[0]}") from exc
    if not params:
        raise CliError(f"{args.parameter_file} has no parameters for {node}")
    with cli_node() as cli:
        cli.require_node(node)
        results = cli.call(SetParameters, f"{node}/set_parameters",
                           SetParameters.Request(parameters=list(params.values()))).results
    failed = 0
    for param, result in zip(params.values(), results, strict=False):
        reason = f": {result.reason}" if result.reason else ""
        if result.successful:
            print(f"Set parameter {param.name} successful{reason}")
        else:
            failed += 1
            print(f"Set parameter {param.name} failed{reason}", file=sys.stderr)
    return 1 if failed else 0


def _describe(args: argparse.Namespace) -> int:
    node = absolute(args.node_name)
    with cli_node() as cli:
        cli.require_node(node)
        described = cli.call(DescribeParameters, f"{node}/describe_parameters",
                             DescribeParameters.Request(names=args.parameter_names))
    for d in described.descriptors:
        print("Parameter name:", d.name)
        print("  Type:", _LABELS.get(d.type, ("", str(d.type)))[1])
        if d.description:
            print("  Description:", d.description)
        if d.additional_constraints or d.read_only or d.floating_point_range \
                or d.integer_range:
            print("  Constraints:")
            if d.read_only:
                print("    Read only: true")
            for range_ in [*d.floating_point_range, *d.integer_range]:
                print("    Min value:", range_.from_value)
                print("    Max value:", range_.to_value)
                if range_.step != 0:
                    print("    Step:", range_.step)
            if d.additional_constraints:
                print("    Additional constraints:", d.additional_constraints)
    return 0
