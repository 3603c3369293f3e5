"""What `ros2 node/topic/service list`, `ros2 service call` and `ros2 param` tell, from rclpy.

The venv has the ROS 2 Jazzy wheels but no `ros2` command (its CLI packages are not on
PyPI), so `fmm ros` asks the graph through rclpy's own introspection: the node names,
topics and services discovery found, a service call, and a node's parameter services
(`rclpy.parameter_client.AsyncParameterClient`). `GraphProbe` joins the graph of the shell's
ROS_DOMAIN_ID (and ROS_AUTOMATIC_DISCOVERY_RANGE) as one short-lived node on a private
context, through `InProcessGraph`, which owns the safe teardown order.
"""

from __future__ import annotations

import os
import threading
import time
from dataclasses import dataclass

from rcl_interfaces.msg import ParameterDescriptor, ParameterType
from rclpy.node import Node
from rclpy.parameter import parameter_value_to_python
from rclpy.parameter_client import AsyncParameterClient

from fmm_ros.ros.graph import InProcessGraph

PROBE_NODE = 'fmm_cli'
# Discovery finds node names before their endpoints; a listing is taken once it has not
# changed for SETTLED_S, or after SETTLE_TIMEOUT_S at most.
SETTLED_S = 0.5
SETTLE_TIMEOUT_S = 5.0
POLL_S = 0.1
TYPE_NAMES = {
    value: name.removeprefix('PARAMETER_').lower()
    for name, value in vars(ParameterType).items()
    if name.startswith('PARAMETER_')
}


@dataclass(frozen=True)
class ParameterInfo:
    """A node's parameter as `ros2 param describe` shows it, with its current value."""

    name: str
    type: str
    description: str
    read_only: bool
    value: object
    constraints: str
    """Range or additional constraints in words ('' when none)."""


class GraphProbe:
    """One node in the shell's ROS graph, for looking around and calling services."""

    def __init__(self, *, discovery_s: float = 2.0) -> None:
        domain = int(os.environ.get('ROS_DOMAIN_ID', '0') or 0)
        self._graph = InProcessGraph(domain_id=domain, localhost_only=False)
        self._discovery_s = discovery_s
        self.node: Node | None = None

    def __enter__(self) -> GraphProbe:
        self._graph.__enter__()
        self.node = self._graph.add(lambda **kwargs: Node(PROBE_NODE, **kwargs))
        self._graph.start()
        time.sleep(self._discovery_s)  # discovery of the others takes this long
        self._wait_for_endpoints()
        return self

    def __exit__(self, *exc_info: object) -> None:
        self._graph.close()

    def nodes(self) -> list[str]:
        """Full names of the graph's nodes (not this one), sorted."""
        return self._settled(
            lambda: sorted(
                f'{namespace.rstrip("/")}/{name}'
                for name, namespace in self.node.get_node_names_and_namespaces()
                if name != PROBE_NODE
            )
        )

    def topics(self) -> list[tuple[str, list[str]]]:
        """(name, types) of every topic, sorted."""
        return self._settled(lambda: sorted(self.node.get_topic_names_and_types()))

    def services(self) -> list[tuple[str, list[str]]]:
        """(name, types) of every service but this node's own, sorted."""
        own = f'/{PROBE_NODE}/'
        return self._settled(
            lambda: sorted(
                (name, types)
                for name, types in self.node.get_service_names_and_types()
                if not name.startswith(own)
            )
        )

    def _wait_for_endpoints(self) -> None:
        """Wait until every node found shows its services (each has parameter services).

        Discovery announces a node before its endpoints; a listing taken in between would
        miss them.
        """
        deadline = time.monotonic() + SETTLE_TIMEOUT_S
        while time.monotonic() < deadline:
            pending = [
                (name, namespace)
                for name, namespace in self.node.get_node_names_and_namespaces()
                if name != PROBE_NODE
                and not self.node.get_service_names_and_types_by_node(name, namespace)
            ]
            if not pending:
                return
            time.sleep(POLL_S)

    @staticmethod
    def _settled(query):
        """query() once its answer has stopped changing (discovery still arriving)."""
        deadline = time.monotonic() + SETTLE_TIMEOUT_S
        answer, since = query(), time.monotonic()
        while time.monotonic() < deadline and time.monotonic() - since < SETTLED_S:
            time.sleep(POLL_S)
            latest = query()
            if latest != answer:
                answer, since = latest, time.monotonic()
        return answer

    def call(self, service_type: type, name: str, request: object, timeout_s: float) -> object:
        """Call a service and wait for its response (TimeoutError if none comes)."""
        client = self.node.create_client(service_type, name)
        try:
            return self._graph.call(client, request, timeout_s=timeout_s)
        finally:
            self.node.destroy_client(client)

    def parameters(
        self, node_name: str, names: list[str] | None = None, timeout_s: float = 5.0
    ) -> list[ParameterInfo]:
        """Every parameter of a node (or the ones named) described, with its value."""
        client = AsyncParameterClient(self.node, node_name.lstrip('/'))
        if not client.wait_for_services(timeout_sec=timeout_s):
            raise TimeoutError(
                f'node {node_name} answers no parameter services within {timeout_s:g} s '
                f'(running? same ROS_DOMAIN_ID? nodes: {", ".join(self.nodes()) or "none"})'
            )
        if not names:
            names = sorted(self._wait(client.list_parameters(), timeout_s).result.names)
        descriptors = self._wait(client.describe_parameters(names), timeout_s).descriptors
        values = self._wait(client.get_parameters(names), timeout_s).values
        return [
            _info(descriptor, parameter_value_to_python(value))
            for descriptor, value in zip(descriptors, values, strict=True)
        ]

    @staticmethod
    def _wait(future, timeout_s: float):
        done = threading.Event()
        future.add_done_callback(lambda _: done.set())
        if not done.wait(timeout_s):
            raise TimeoutError(f'no answer within {timeout_s:g} s')
        return future.result()


def _info(descriptor: ParameterDescriptor, value: object) -> ParameterInfo:
    ranges = [
        f'{span.from_value:g} to {span.to_value:g}'
        for span in (*descriptor.floating_point_range, *descriptor.integer_range)
    ]
    constraints = '; '.join(filter(None, (*ranges, descriptor.additional_constraints)))
    return ParameterInfo(
        descriptor.name,
        TYPE_NAMES.get(descriptor.type, str(descriptor.type)),
        descriptor.description,
        descriptor.read_only,
        value,
        constraints,
    )
