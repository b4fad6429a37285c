"""``ros2 node list|info``, in ros2cli's formats."""

from __future__ import annotations

import argparse
import sys

from ._graph import absolute, cli_node
from ._main import Commands, add_spin_time, add_verbs, verb
from .errors import CliError


def register(commands: Commands) -> None:
    verbs = add_verbs(commands, "node", "Various node related sub-commands")
    p = verb(verbs, "list", "Output a list of available nodes", _list)
    add_spin_time(p)
    p.add_argument("-a", "--all", action="store_true", help="Display all nodes even hidden ones")
    p.add_argument("-c", "--count-nodes", action="store_true",
                   help="Only display the number of nodes discovered")
    p = verb(verbs, "info", "Output information about a node", _info)
    p.add_argument("node_name", help="Node name to request information")
    p.add_argument("--include-hidden", action="store_true", help="Display hidden topics, "
                   "services, and actions as well")


def _list(args: argparse.Namespace) -> int:
    with cli_node() as node:
        node.settle(min_s=args.spin_time)
        names = node.node_names(include_hidden=args.all)
        own = node.node.get_fully_qualified_name()
    names = [n for n in names if n != own]
    if args.count_nodes:
        print(len(names))
    else:
        for name in names:
            print(name)
    return 0


def _hidden(name: str) -> bool:
    return any(part.startswith("_") for part in name.split("/"))


def _info(args: argparse.Namespace) -> int:
    fqn = absolute(args.node_name)
    with cli_node() as cli:
        name, namespace = cli.require_node(fqn)
        cli.settle(min_s=0.0)
        count = cli.node_names(include_hidden=True).count(fqn)
        if count > 1:
            print(f"There are {count} nodes in the graph with the exact name \"{fqn}\". You are "
                  "seeing information about only one of them.", file=sys.stderr)
        node = cli.node
        try:
            sections = [
                ("Subscribers", node.get_subscriber_names_and_types_by_node(name, namespace)),
                ("Publishers", node.get_publisher_names_and_types_by_node(name, namespace)),
                ("Service Servers", node.get_service_names_and_types_by_node(name, namespace)),
                ("Service Clients", node.get_client_names_and_types_by_node(name, namespace)),
            ]
        except Exception as exc:  # the node left between the two queries
            raise CliError(f"Unable to find node '{fqn}': {exc}") from exc
    print(fqn)
    for title, entries in [*sections, ("Action Servers", []), ("Action Clients", [])]:
        print(f"  {title}:")
        for topic, types in sorted(entries):
            if args.include_hidden or not _hidden(topic):
                print(f"    {topic}: {', '.join(types)}")
    return 0
