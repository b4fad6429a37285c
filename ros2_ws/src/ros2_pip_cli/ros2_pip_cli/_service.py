"""``ros2 service list|type|call``, in ros2cli's formats."""

from __future__ import annotations

import argparse
import time

from ._fill import parse_values, read_values, set_message_fields
from ._graph import CliNode, cli_node, resolve_name
from ._main import Commands, add_list_verb, add_verbs, print_names, verb
from ._messages import import_interface
from ._view import Query, graph_view
from .errors import CliError


def register(commands: Commands) -> None:
    verbs = add_verbs(commands, "service", "Various service related sub-commands")
    add_list_verb(verbs, "service", _list)
    p = verb(verbs, "type", "Output a service's type", _type)
    p.add_argument("service_name")
    p = verb(verbs, "call", "Call a service", _call)
    p.add_argument("service_name", help="Name of the ROS service to call (e.g. '/add_two_ints')")
    p.add_argument("service_type", nargs="?",
                   help="Type of the ROS service (e.g. 'std_srvs/srv/Empty'); "
                        "looked up in the graph when left out")
    p.add_argument("values", nargs="?", default=None,
                   help="Values to fill the request with in YAML format, e.g. '{a: 1, b: 2}'")
    p.add_argument("--stdin", action="store_true", help="Read values from standard input")
    p.add_argument("-r", "--rate", type=float, metavar="N",
                   help="Repeat the call at a specific rate in Hz")


def _hidden(name: str) -> bool:
    return any(part.startswith("_") for part in name.split("/"))


def _list(args: argparse.Namespace) -> int:
    services = graph_view(args, Query()).services
    return print_names([s for s in services if args.include_hidden or not _hidden(s[0])], args)


def _types(node: CliNode, service: str) -> list[str]:
    found: list[str] = []

    def seen() -> bool:
        found[:] = dict(node.node.get_service_names_and_types()).get(service, [])
        return bool(found)

    if not node.wait_for(seen):
        raise CliError(f"Unknown service '{service}'")
    return found


def _type(args: argparse.Namespace) -> int:
    service = resolve_name(args.service_name, kind="service")
    types = graph_view(args, Query(wait_kind="service", wait_name=service)).service_types(service)
    if not types:
        raise CliError(f"Unknown service '{service}'")
    for name in types:
        print(name)
    return 0


def _call(args: argparse.Namespace) -> int:
    if args.service_type is not None and "/" not in args.service_type:
        # `ros2 service call /x '{a: 1}'`: the type was left out, the values given.
        args.values, args.service_type = args.service_type, None
    if args.rate is not None and not args.rate > 0:
        raise CliError("--rate must be > 0")
    with cli_node() as node:
        service = node.resolve(args.service_name, kind="service")
        type_name = args.service_type or _types(node, service)[0]
        srv = import_interface(type_name, "srv")
        request = srv.Request()
        set_message_fields(request, parse_values(read_values(args)))
        client = node.node.create_client(srv, service)
        if not client.service_is_ready():
            print("waiting for service to become available...", flush=True)
            node.wait_for(client.service_is_ready, timeout_s=float("inf"))
        while True:
            started = time.monotonic()
            print(f"requester: making request: {request!r}\n", flush=True)
            future = client.call_async(request)
            node.wait_for(future.done, timeout_s=float("inf"))
            if future.exception() is not None:
                raise CliError(f"Exception while calling service: {future.exception()!r}")
            print(f"response:\n{future.result()!r}\n", flush=True)
            if args.rate is None:
                return 0
            pause = started + 1.0 / args.rate - time.monotonic()
            if pause > 0:
                node.wait_for(lambda: False, timeout_s=pause)
