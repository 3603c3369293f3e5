"""Run several ROS 2 nodes in one process on a private context, with a safe teardown.

Used by the launch-free test scripts, the one-process rig launch script and `fmm demo`.
rclpy Jazzy's `init()` is no context manager and its executors do not join their threads
on shutdown, so this owns the order that avoids errors at exit: stop spinning, shut the
executor down, destroy the nodes, shut the context down.
"""

import os
import random
import threading
import time
from collections.abc import Callable
from typing import TypeVar

import rclpy
from rclpy.client import Client
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node

NodeT = TypeVar('NodeT', bound=Node)

# Domain ids a private graph picks from; LOCALHOST discovery keeps the traffic on this host.
PRIVATE_DOMAIN_IDS = range(1, 101)


def private_domain_ids() -> range:
    """The share of PRIVATE_DOMAIN_IDS this process draws from.

    All of them, except under pytest-xdist: worker gwN of M takes every M-th id from the N-th,
    so graphs of tests running side by side never share a domain. Processes a test starts
    inherit the worker's environment, so they draw from its share too.
    """
    worker = os.environ.get('PYTEST_XDIST_WORKER', '')
    workers = int(os.environ.get('PYTEST_XDIST_WORKER_COUNT', '1'))
    if not worker.startswith('gw') or workers < 2:
        return PRIVATE_DOMAIN_IDS
    shares = min(workers, len(PRIVATE_DOMAIN_IDS))
    return PRIVATE_DOMAIN_IDS[int(worker[2:]) % shares :: shares]


def private_domain_id() -> int:
    """A domain id drawn at random from this process's share (`private_domain_ids`)."""
    return random.choice(private_domain_ids())


class InProcessGraph:
    """Nodes sharing one private Context and one executor spun in a background thread.

    Usage::

        with InProcessGraph() as graph:
            talker = graph.add(Talker)
            graph.start()
            ...
    """

    def __init__(
        self,
        *,
        domain_id: int | None = None,
        localhost_only: bool = True,
        spin_period_s: float = 0.05,
    ) -> None:
        if localhost_only:
            # Read by the middleware at context init: discovery stays on this host.
            os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
        self.domain_id = private_domain_id() if domain_id is None else domain_id
        self.context = Context()
        self._spin_period_s = spin_period_s
        self._nodes: list[Node] = []
        self._executor: SingleThreadedExecutor | None = None
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()

    def __enter__(self) -> 'InProcessGraph':
        rclpy.init(context=self.context, domain_id=self.domain_id)
        self._executor = SingleThreadedExecutor(context=self.context)
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    def add(self, node_factory: Callable[..., NodeT], **kwargs: object) -> NodeT:
        """Create a node on this graph's context (`node_factory(context=..., **kwargs)`)."""
        node = node_factory(context=self.context, **kwargs)
        self._nodes.append(node)
        self._executor.add_node(node)
        return node

    def start(self, discovery_timeout_s: float = 10.0) -> None:
        """Wait until the graph's publishers see its subscribers, then spin until close().

        Sample batches are VOLATILE: one published before its subscriber is matched is lost,
        and an accelerated session publishes its first hit within milliseconds.
        """
        self.wait_for_discovery(discovery_timeout_s)
        if self._thread is None:
            self._thread = threading.Thread(target=self._spin, name='fmm-graph', daemon=True)
            self._thread.start()

    def wait_for_discovery(self, timeout_s: float) -> None:
        """Block until every publisher has matched each subscription to its topic in the graph."""
        wanted = {}
        for node in self._nodes:
            for subscription in node.subscriptions:
                wanted[subscription.topic_name] = wanted.get(subscription.topic_name, 0) + 1
        publishers = [
            publisher
            for node in self._nodes
            for publisher in node.publishers
            if publisher.topic_name in wanted
        ]
        deadline = time.monotonic() + timeout_s
        for publisher in publishers:
            while publisher.get_subscription_count() < wanted[publisher.topic_name]:
                if time.monotonic() > deadline:
                    raise TimeoutError(
                        f'{publisher.topic_name}: {publisher.get_subscription_count()} of '
                        f'{wanted[publisher.topic_name]} subscribers matched after {timeout_s} s'
                    )
                time.sleep(0.005)

    def _spin(self) -> None:
        while not self._stop.is_set() and self.context.ok():
            self._executor.spin_once(timeout_sec=self._spin_period_s)

    def call(self, client: Client, request: object, timeout_s: float = 10.0) -> object:
        """Call a service from outside the executor thread and wait for the response."""
        if not client.wait_for_service(timeout_sec=timeout_s):
            raise TimeoutError(f'service {client.srv_name} not available after {timeout_s} s')
        future = client.call_async(request)
        done = threading.Event()
        future.add_done_callback(lambda _: done.set())
        if not done.wait(timeout_s):
            client.remove_pending_request(future)
            raise TimeoutError(f'service {client.srv_name} did not answer within {timeout_s} s')
        return future.result()

    def close(self) -> None:
        """Tear down in the safe order; safe to call twice."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join()
            self._thread = None
        if self._executor is not None:
            self._executor.shutdown()
            self._executor = None
        for node in self._nodes:
            node.destroy_node()
        self._nodes.clear()
        self.context.try_shutdown()
