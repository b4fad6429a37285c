"""``ros2 component list|load|unload`` against efficient_comm containers.

ros2cli talks to rclcpp containers through composition_interfaces; an efficient_comm
container offers the same three operations as ``<container>/list_components``,
``load_component`` and ``unload_component`` (efficient_comm_interfaces). The plug-in is an
efficient_comm class path (``my_pkg.shout:Shouter``) or a component entry point name.
"""

from __future__ import annotations

import argparse
from typing import Any

import yaml

from efficient_comm_interfaces.srv import ListComponents, LoadComponent, UnloadComponent

from ._graph import CliNode, absolute, cli_node, full_name
from ._main import Commands, add_spin_time, add_verbs, verb
from .errors import CliError

_LIST_TYPE = "efficient_comm_interfaces/srv/ListComponents"


def register(commands: Commands) -> None:
    verbs = add_verbs(commands, "component", "Various component related sub-commands "
                      "(efficient_comm containers)")
    p = verb(verbs, "list", "Output a list of running containers and components", _list)
    add_spin_time(p)
    p.add_argument("container_node_name", nargs="?", help="Name of the container node to list")
    p.add_argument("--containers-only", action="store_true",
                   help="List found containers nodes only")
    p = verb(verbs, "load", "Load a component into a container node", _load)
    p.add_argument("container_node_name")
    p.add_argument("package_name", help="Package the component's class belongs to")
    p.add_argument("plugin_name", help="efficient_comm class path (my_pkg.module:Class) or a "
                   "component entry point name")
    p.add_argument("-n", "--node-name", help="Component node name (default: the class name "
                   "in lower case)")
    p.add_argument("--node-namespace", default="", help="Component node namespace")
    p.add_argument("-r", "--remap-rule", action="append", default=[], metavar="FROM:=TO",
                   help="Component node remapping rules")
    p.add_argument("-p", "--parameter", action="append", default=[], metavar="NAME:=VALUE",
                   help="Component node parameters (values in YAML)")
    p.add_argument("-q", "--quiet", action="store_true",
                   help="Only print component unique ID and name")
    p = verb(verbs, "unload", "Unload a component from a container node", _unload)
    p.add_argument("container_node_name")
    p.add_argument("component_uid", type=int, nargs="+", help="Component unique IDs")
    p.add_argument("-q", "--quiet", action="store_true", help="Only print component unique IDs")


def containers(cli: CliNode) -> list[str]:
    """Nodes that offer efficient_comm's ``list_components`` service."""
    found = []
    for name, namespace in cli.node.get_node_names_and_namespaces():
        fqn = full_name(name, namespace)
        try:
            services = cli.node.get_service_names_and_types_by_node(name, namespace)
        except Exception:  # left the graph meanwhile
            continue
        if any(s == f"{fqn}/list_components" and _LIST_TYPE in t for s, t in services):
            found.append(fqn)
    return sorted(found)


def _require_container(cli: CliNode, name: str) -> str:
    fqn = absolute(name)
    if not cli.wait_for(lambda: fqn in containers(cli)):
        raise CliError(f"Unable to find container node '{fqn}'")
    return fqn


def _components(cli: CliNode, container: str) -> list[tuple[int, str]]:
    response = cli.call(ListComponents, f"{container}/list_components",
                        ListComponents.Request())
    return list(zip(response.unique_ids, response.full_node_names, strict=False))


def _list(args: argparse.Namespace) -> int:
    with cli_node() as cli:
        if args.container_node_name is not None:
            name = _require_container(cli, args.container_node_name)
            if not args.containers_only:
                for uid, node in _components(cli, name):
                    print(f"{uid}  {node}")
            return 0
        cli.settle(min_s=args.spin_time)
        for name in containers(cli):
            print(name)
            if not args.containers_only:
                for uid, node in _components(cli, name):
                    print(f"  {uid}  {node}")
    return 0


def _parameters_yaml(fqn: str, items: list[str]) -> str:
    values: dict[str, Any] = {}
    for item in items:
        name, sep, text = item.partition(":=")
        if not sep or not name:
            raise CliError(f"parameter {item!r} is not NAME:=VALUE")
        try:
            values[name] = yaml.safe_load(text)
        except yaml.YAMLError:
            values[name] = text
    return yaml.safe_dump({fqn: {"ros__parameters": values}}) if values else ""


def _load(args: argparse.Namespace) -> int:
    plugin = args.plugin_name
    node_name = args.node_name or plugin.replace("::", ":").split(":")[-1].split(".")[-1].lower()
    namespace = args.node_namespace or "/"
    fqn = full_name(node_name, absolute(namespace) if namespace != "/" else "/")
    request = LoadComponent.Request(
        class_path=plugin, node_name=node_name, node_namespace=args.node_namespace,
        remap_rules=list(args.remap_rule),
        parameters_yaml=_parameters_yaml(fqn, args.parameter))
    with cli_node() as cli:
        container = _require_container(cli, args.container_node_name)
        response = cli.call(LoadComponent, f"{container}/load_component", request)
    if not response.success:
        # The container's message may carry the constructor's traceback: its last line says why.
        why = (response.error_message.strip().splitlines() or ["no reason given"])[-1]
        raise CliError(f"Failed to load component: {why}")
    if args.quiet:
        print(f"{response.unique_id}  {response.full_node_name}")
    else:
        print(f"Loaded component {response.unique_id} into '{container}' container node as "
              f"'{response.full_node_name}'")
    return 0


def _unload(args: argparse.Namespace) -> int:
    failed = []
    with cli_node() as cli:
        container = _require_container(cli, args.container_node_name)
        for uid in args.component_uid:
            response = cli.call(UnloadComponent, f"{container}/unload_component",
                                UnloadComponent.Request(unique_id=uid))
            if not response.success:
                failed.append(f"Failed to unload component {uid} from '{container}' "
                              f"container node: {response.error_message}")
            elif args.quiet:
                print(uid)
            else:
                print(f"Unloaded component {uid} from '{container}' container node")
    if failed:
        raise CliError("; ".join(failed))
    return 0
