"""Read and change another node's parameters (``rclpy.parameter_client.AsyncParameterClient``).

Every method sends one request and returns a :class:`~dptpu.graph.task.Future` whose result is the
service response (as rclpy). The ``*_values`` helpers convert to plain Python, which is what the
``dptpu param`` CLI needs::

    client = AsyncParameterClient(node, "/scanner/phase_node")
    client.wait_for_services(timeout_sec=2.0)
    future = client.get_parameters(["steps"])
    dptpu.graph.spin_until_future_complete(node, future, timeout_sec=2.0)
    print(client.values_of(future.result()))        # [12]
"""

from __future__ import annotations

import time

from .parameters import Parameter, parameter_value_to_python
from .qos import qos_profile_services_default
from .rcl_interfaces import (
    DescribeParameters,
    GetParameters,
    GetParameterTypes,
    ListParameters,
    SetParameters,
    SetParametersAtomically,
    strings,
    texts,
)

__all__ = ["AsyncParameterClient"]


class AsyncParameterClient:
    """Clients of the parameter services of ``remote_node_name`` (relative names use ``node``'s namespace)."""

    def __init__(self, node, remote_node_name: str, qos_profile=qos_profile_services_default, callback_group=None):
        self._node = node
        target = node.resolve_service_name(remote_node_name, only_expand=True)
        self.remote_node_name = target

        def client(srv_type, suffix):
            return node.create_client(srv_type, f"{target}/{suffix}", qos_profile=qos_profile,
                                      callback_group=callback_group)

        self._get = client(GetParameters, "get_parameters")
        self._types = client(GetParameterTypes, "get_parameter_types")
        self._set = client(SetParameters, "set_parameters")
        self._set_atomic = client(SetParametersAtomically, "set_parameters_atomically")
        self._list = client(ListParameters, "list_parameters")
        self._describe = client(DescribeParameters, "describe_parameters")
        self._clients = (self._get, self._types, self._set, self._set_atomic, self._list, self._describe)

    def services_are_ready(self) -> bool:
        return all(c.service_is_ready() for c in self._clients)

    def wait_for_services(self, timeout_sec: float | None = None) -> bool:
        deadline = None if timeout_sec is None else time.monotonic() + timeout_sec
        for client in self._clients:
            remaining = None if deadline is None else max(0.0, deadline - time.monotonic())
            if not client.wait_for_service(remaining):
                return False
        return True

    def get_parameters(self, names):
        return self._get.call_async(GetParameters.Request(names=strings(names)))

    def get_parameter_types(self, names):
        return self._types.call_async(GetParameterTypes.Request(names=strings(names)))

    def set_parameters(self, parameters):
        """``parameters``: a list of :class:`~dptpu.graph.Parameter`."""
        return self._set.call_async(SetParameters.Request(parameters=[p.to_parameter_msg() for p in parameters]))

    def set_parameters_atomically(self, parameters):
        return self._set_atomic.call_async(
            SetParametersAtomically.Request(parameters=[p.to_parameter_msg() for p in parameters]))

    def list_parameters(self, prefixes=None, depth: int = 0):
        return self._list.call_async(ListParameters.Request(prefixes=strings(prefixes or []), depth=depth))

    def describe_parameters(self, names):
        return self._describe.call_async(DescribeParameters.Request(names=strings(names)))

    @staticmethod
    def values_of(response) -> list:
        """Python values of a GetParameters response (None for a parameter the node does not have)."""
        return [parameter_value_to_python(v) for v in response.values]

    @staticmethod
    def names_of(response) -> list[str]:
        """Names in a ListParameters response."""
        return texts(response.result.names)

    def destroy(self) -> None:
        for client in self._clients:
            self._node.destroy_client(client)


def parameters_from_values(values: dict) -> list[Parameter]:
    """``{"steps": 12}`` -> ``[Parameter("steps", value=12)]``."""
    return [Parameter(name, value=value) for name, value in values.items()]
