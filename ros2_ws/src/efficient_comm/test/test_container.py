"""Container files and composition: bad input is reported by file and entry, the rest runs."""

from __future__ import annotations

from pathlib import Path
from typing import ClassVar

import pytest
from std_msgs.msg import String

from efficient_comm import ComponentError, ConfigError, Container
from efficient_comm.handle import NodeHandle
from efficient_comm.testing import ManualClock


class Greeter:
    def __init__(self, node: NodeHandle) -> None:
        self.greeting = node.declare_parameter("greeting", "hello")
        self.rate = node.declare_parameter("rate_hz", 1.0)
        self.pub = node.create_publisher(String, "greeting")


class Exploding:
    def __init__(self, node: NodeHandle) -> None:
        node.create_publisher(String, "half_built")
        raise RuntimeError("no camera attached")


class Closeable:
    closed: ClassVar[list[str]] = []

    def __init__(self, node: NodeHandle) -> None:
        self.name = node.name

    def close(self) -> None:
        Closeable.closed.append(self.name)


HERE = "test.test_container"


def _container() -> Container:
    return Container("c", dds=False, clock=ManualClock(), serve=False)


def _write(tmp_path: Path, text: str, name: str = "c.yaml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def test_file_with_params_layout_remaps_and_namespaces(tmp_path: Path) -> None:
    _write(tmp_path, "/**:\n  ros__parameters: {rate_hz: 5.0}\n", "common.yaml")
    path = _write(
        tmp_path,
        f"""
parameter_files: [common.yaml]
components:
  - class: {HERE}:Greeter
    name: greeter
    namespace: /robot
    remappings: ["greeting:=/announce"]
    parameters:
      /robot/greeter:
        ros__parameters: {{greeting: ahoy}}
      /other:
        ros__parameters: {{greeting: wrong}}
""",
    )
    with _container() as container:
        report = container.load_file(path)
        assert report.errors == []
        (loaded,) = report.loaded
        assert loaded.full_node_name == "/robot/greeter"
        assert loaded.instance.greeting == "ahoy" and loaded.instance.rate == 5.0
        assert loaded.instance.pub.topic_name == "/announce"


def test_bad_entries_are_reported_by_file_and_entry_and_the_rest_loads(tmp_path: Path) -> None:
    path = _write(
        tmp_path,
        f"""
components:
  - {{class: {HERE}:Greeter, name: good}}
  - {{class: {HERE}:NoSuchClass, name: missing}}
  - {{class: no_such_module:Thing, name: nomodule}}
  - {{class: {HERE}:Greeter, name: good}}
  - {{class: {HERE}:Exploding, name: exploding}}
  - {{class: {HERE}:Greeter, name: "bad name"}}
  - {{class: {HERE}:Greeter, name: typo, remapings: {{}}}}
  - {{class: {HERE}:Greeter, name: badtopic, remappings: {{greeting: "not valid//"}}}}
  - class: {HERE}:Greeter
    name: wrongtype
    parameters: {{/**: {{ros__parameters: {{rate_hz: fast}}}}}}
  - just a string
""",
    )
    with _container() as container:
        report = container.load_file(path)
        assert [c.full_node_name for c in report.loaded] == ["/good"]
        messages = [str(e) for e in report.errors]
        assert len(messages) == 9
        for index, text in zip([1, 2, 3, 4, 5, 6, 7, 8, 9], messages, strict=True):
            assert f"{path}: components[{index}]" in text
        assert "NoSuchClass" in messages[0] and "no_such_module" in messages[1]
        assert "already taken" in messages[2]
        assert "no camera attached" in messages[3]
        assert "remapings" in messages[5]
        assert "rate_hz" in messages[7]
        # The constructor that raised left nothing behind on the bus.
        assert "/half_built" not in container.bus.topics()


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("components: [\n", "invalid YAML"),
        ("just text", "'components' list"),
        ("components:\n  - {class: x:Y, name: n, parameters: {n: {rate: 1}}}", "ros__parameters"),
    ],
)
def test_unusable_files_are_reported(tmp_path: Path, text: str, expected: str) -> None:
    path = _write(tmp_path, text)
    with _container() as container:
        report = container.load_file(path)
        assert report.loaded == []
        assert expected in str(report.errors[0]) and str(path) in str(report.errors[0])


def test_missing_file_is_reported(tmp_path: Path) -> None:
    with _container() as container:
        report = container.load_file(tmp_path / "nope.yaml")
        assert "cannot read" in str(report.errors[0])


def test_entry_points_load_by_name() -> None:
    from efficient_comm.config import ComponentSpec

    with _container() as container:
        loaded = container.load(ComponentSpec(class_path="camera", name="cam"))
        assert type(loaded.instance).__name__ == "Camera"
        with pytest.raises(ConfigError, match="no entry point"):
            container.load(ComponentSpec(class_path="no_such_component", name="x"))
        # A registered name in ROS's plugin style is an entry point name, not module:Class.
        with pytest.raises(ConfigError, match="no entry point 'efficient_comm::nothing'"):
            container.load(ComponentSpec(class_path="efficient_comm::nothing", name="y"))


def test_unload_calls_close_and_frees_the_name() -> None:
    with _container() as container:
        instance = container.add(Closeable, name="closeable")
        (loaded,) = container.components()
        container.unload(loaded.unique_id)
        assert Closeable.closed[-1] == instance.name
        container.add(Closeable, name="closeable")  # the name is free again
        with pytest.raises(ComponentError):
            container.unload(999)


def test_an_interrupt_while_one_component_closes_closes_the_others_first() -> None:
    # A second SIGTERM during shutdown (the stopping parent died) interrupted the first
    # component's close; the others stayed open, and one with a non-daemon thread (Zenoh's)
    # kept the process alive for good.
    class Interrupted:
        def __init__(self, node: NodeHandle) -> None:
            pass

        def close(self) -> None:
            raise KeyboardInterrupt

    container = _container()
    first = container.add(Closeable, name="first")
    container.add(Interrupted, name="interrupted")  # newest: closed first
    with pytest.raises(KeyboardInterrupt):
        container.close()
    assert Closeable.closed[-1] == first.name


def test_a_composed_component_reaches_its_container() -> None:
    class Probe:
        def __init__(self, node: NodeHandle) -> None:
            self.container = getattr(node, "container", None)

    with _container() as container:
        assert container.add(Probe, name="probe").container is container
