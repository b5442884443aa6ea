"""The standard parameter services every node serves (``rclpy.parameter_service.ParameterService``).

``~/get_parameters``, ``~/get_parameter_types``, ``~/set_parameters``, ``~/set_parameters_atomically``,
``~/list_parameters`` and ``~/describe_parameters`` with ``rcl_interfaces`` types, so
``dptpu param get/set/dump`` (through :class:`~dptpu.graph.parameter_client.AsyncParameterClient`) can
read and change any node's parameters. Undeclared names give NOT_SET values and failed results, not
errors, as in ROS 2.
"""

from __future__ import annotations

import numpy as np

from .exceptions import ParameterException
from .parameters import Parameter
from .rcl_interfaces import (
    DescribeParameters,
    GetParameters,
    GetParameterTypes,
    ListParameters,
    ParameterDescriptor,
    ParameterValue,
    SetParameters,
    SetParametersAtomically,
    SetParametersResult,
    texts,
)

__all__ = ["ParameterService"]


class ParameterService:
    """Creates the six parameter services on ``node``."""

    def __init__(self, node):
        self._node = node
        for name, srv_type, handler in (
                ("~/describe_parameters", DescribeParameters, self._describe),
                ("~/get_parameters", GetParameters, self._get),
                ("~/get_parameter_types", GetParameterTypes, self._get_types),
                ("~/list_parameters", ListParameters, self._list),
                ("~/set_parameters", SetParameters, self._set),
                ("~/set_parameters_atomically", SetParametersAtomically, self._set_atomically)):
            node.create_service(srv_type, name, handler)

    def _get(self, request, response):
        store = self._node._parameters
        for name in texts(request.names):
            try:
                response.values.append(store.get(name).get_parameter_value())
            except ParameterException:
                response.values.append(ParameterValue())
        return response

    def _get_types(self, request, response):
        store = self._node._parameters
        types = []
        for name in texts(request.names):
            types.append(int(store.get_or(name).type_) if store.has(name) else 0)
        response.types = np.asarray(types, dtype=np.uint8)
        return response

    def _describe(self, request, response):
        store = self._node._parameters
        for name in texts(request.names):
            try:
                response.descriptors.append(store.describe(name))
            except ParameterException:
                response.descriptors.append(ParameterDescriptor(name=name))
        return response

    def _list(self, request, response):
        response.result = self._node._parameters.list(texts(request.prefixes), int(request.depth))
        return response

    def _parameters(self, request):
        return [Parameter.from_parameter_msg(p) for p in request.parameters]

    def _set(self, request, response):
        store = self._node._parameters
        for msg in request.parameters:
            try:
                response.results.extend(store.set([Parameter.from_parameter_msg(msg)]))
            except ParameterException as exc:
                response.results.append(SetParametersResult(successful=False, reason=str(exc)))
        return response

    def _set_atomically(self, request, response):
        try:
            response.result = self._node._parameters.set_atomically(self._parameters(request))
        except ParameterException as exc:
            response.result = SetParametersResult(successful=False, reason=str(exc))
        return response
