"""Services and parameter services across processes, with the client started before the server."""

from __future__ import annotations

import json

import pytest

from dptpu.graph import AsyncParameterClient, Node, Parameter, ServiceCallError, SetBool, Trigger


def test_service_call_across_processes_and_error_reply(context, spawn):
    node = Node("caller", context=context)
    client = node.create_client(SetBool, "/param_node/toggle")
    assert not client.service_is_ready()
    server = spawn("param_node")
    assert client.wait_for_service(timeout_sec=5.0)
    response = client.call(SetBool.Request(data=True), timeout_sec=5.0)
    assert (response.success, response.message) == (True, "on")
    with pytest.raises(ServiceCallError, match="ValueError: refused to switch off"):
        client.call(SetBool.Request(data=False), timeout_sec=5.0)
    # the server survived its callback's exception and still answers
    report = node.create_client(Trigger, "/param_node/report")
    assert report.wait_for_service(timeout_sec=5.0)
    assert json.loads(report.call(Trigger.Request(), timeout_sec=5.0).message)["a"] == 0
    assert server.wait_for_stderr("exception in service callback of /param_node/toggle of node /param_node")


def test_parameter_services_get_set_list_across_processes(context, spawn):
    spawn("param_node")
    node = Node("param_cli", context=context)
    remote = AsyncParameterClient(node, "/param_node")
    assert remote.wait_for_services(timeout_sec=5.0)

    def result(future):
        assert future.wait(5.0), "no response"
        return future.result()

    values = remote.values_of(result(remote.get_parameters(["a", "c", "names", "missing"])))
    assert values == [0, "default", ["x"], None]
    refused = result(remote.set_parameters([Parameter("rate_hz", value=0.0)])).results[0]
    assert (refused.successful, refused.reason) == (False, "rate_hz must be > 0")
    wrong_type = result(remote.set_parameters([Parameter("a", value="text")])).results[0]
    assert not wrong_type.successful and "is of type INTEGER, setting it to STRING" in wrong_type.reason
    accepted = result(remote.set_parameters([Parameter("rate_hz", value=5.0), Parameter("a", value=7)])).results
    assert [r.successful for r in accepted] == [True, True]
    assert remote.values_of(result(remote.get_parameters(["rate_hz", "a"]))) == [5.0, 7]
    names = remote.names_of(result(remote.list_parameters()))
    assert names == ["a", "b", "c", "names", "nested.x", "rate_hz", "use_sim_time"]
    descriptor = result(remote.describe_parameters(["nested.x"])).descriptors[0]
    assert (descriptor.name, descriptor.type) == ("nested.x", Parameter.Type.INTEGER)
