"""The container's ROS 2 services: load, unload and list components at run time."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import yaml

from efficient_comm_interfaces.srv import ListComponents, LoadComponent, UnloadComponent

from ._names import check_node_name, fully_qualified, parse_remaps
from ._params import overrides_for
from .config import ComponentSpec
from .errors import EfficientCommError

if TYPE_CHECKING:
    from rclpy.node import Node

    from .container import Container


def serve_container(container: Container, node: Node) -> None:
    """Offer ``~/load_component``, ``~/unload_component`` and ``~/list_components``."""

    def load(request: Any, response: Any) -> Any:
        source = f"load_component request for {request.node_name!r}"
        try:
            name, namespace = check_node_name(request.node_name, request.node_namespace)
            fqn = fully_qualified(name, namespace)
            document = yaml.safe_load(request.parameters_yaml) if request.parameters_yaml else None
            loaded = container.load(
                ComponentSpec(
                    class_path=request.class_path,
                    name=request.node_name,
                    namespace=namespace,
                    remappings=parse_remaps(list(request.remap_rules)),
                    parameters=overrides_for(document, fqn, source=source),
                    source=source,
                )
            )
        except (EfficientCommError, yaml.YAMLError) as exc:
            container.logger.error(str(exc))
            response.success = False
            response.error_message = str(exc)
            return response
        except Exception as exc:  # never let a request take the container down
            container.logger.error(f"{source}: {exc!r}")
            response.success = False
            response.error_message = str(exc)
            return response
        response.success = True
        response.unique_id = loaded.unique_id
        response.full_node_name = loaded.full_node_name
        return response

    def unload(request: Any, response: Any) -> Any:
        try:
            container.unload(request.unique_id)
            response.success = True
        except Exception as exc:  # includes a component's close() that raised
            container.logger.error(f"unload_component {request.unique_id}: {exc!r}")
            response.success = False
            response.error_message = str(exc)
        return response

    def list_components(_request: Any, response: Any) -> Any:
        loaded = container.components()
        response.full_node_names = [c.full_node_name for c in loaded]
        response.unique_ids = [c.unique_id for c in loaded]
        response.class_paths = [c.class_path for c in loaded]
        return response

    node.create_service(LoadComponent, "~/load_component", load)
    node.create_service(UnloadComponent, "~/unload_component", unload)
    node.create_service(ListComponents, "~/list_components", list_components)
