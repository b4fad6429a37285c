"""``ros2 node list|info``, in ros2cli's formats."""

from __future__ import annotations

import argparse
import sys

from ._graph import absolute
from ._main import Commands, add_spin_time, add_verbs, verb
from ._view import Query, graph_view
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
    names = [n for n in graph_view(args, Query()).nodes
             if args.all or not n.rpartition("/")[2].startswith("_")]
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
    view = graph_view(args, Query(wait_kind="node", wait_name=fqn, settle_after_wait=True,
                                  node=fqn))
    count = view.nodes.count(fqn)
    if not count:
        raise CliError(f"Node not found: {fqn}")
    if view.node_error:
        raise CliError(f"Unable to find node '{fqn}': {view.node_error}")
    if count > 1:
        print(f"There are {count} nodes in the graph with the exact name \"{fqn}\". You are "
              "seeing information about only one of them.", file=sys.stderr)
    print(fqn)
    for title, entries in [*view.node_sections, ("Action Servers", []), ("Action Clients", [])]:
        print(f"  {title}:")
        for topic, types in entries:
            if args.include_hidden or not _hidden(topic):
                print(f"    {topic}: {', '.join(types)}")
    return 0
