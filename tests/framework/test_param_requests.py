"""A node's parameter requests (docs/tuning.md): the live marker, and any request from outside the process
answered or refused with a reason, never applied unless valid, in a real runtime."""

from __future__ import annotations

import json

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from pydantic import Field

from handflow.framework.files.params import StrictModel, live, live_keys
from handflow.framework.graphs.model import load_graph
from handflow.framework.network import sessions as transport
from handflow.framework.network.settings import ZenohSettings
from handflow.framework.runtime.live_params import ParamRefused
from handflow.framework.runtime.runner import GroupRuntime
from handflow.plugins.basic.transform import GainOffsetParams


def test_live_marks_fields_and_keeps_their_other_settings():
    class P(StrictModel):
        rate: float = Field(1.0, gt=0)
        gain: float = live(2.0, gt=0, description="g")
        names: list[str] = live(default_factory=list)

    assert live_keys(P) == {"gain", "names"}
    assert P().gain == 2.0 and P().names == []
    assert P.model_json_schema()["properties"]["gain"]["live"] is True
    with pytest.raises(ValueError, match="greater than 0"):
        P(gain=0)
    assert live_keys(GainOffsetParams) == {"gain", "offset"}


@pytest.fixture(scope="module")
def runtime(tmp_path_factory):
    """scale (basic.transform) in a real GroupRuntime on a real hub, its state in a run folder."""
    folder = tmp_path_factory.mktemp("params")
    path = folder / "g.yaml"
    path.write_text(
        "name: preq\nnodes:\n  - id: source\n    plugin: basic.signal\n    params: {rate_hz: 10}\n"
        "  - id: scale\n    plugin: basic.transform\n    params: {gain: 2.0}\n    inputs: {in: source/out}\n"
    )
    hub_ep = transport.hub_endpoint_for()
    hub = transport.open_hub(ZenohSettings(), hub_ep)
    state = folder / "state"
    state.mkdir()
    rt = GroupRuntime(load_graph(path), ["scale"], hub_ep, state_dir=state)
    yield path, hub_ep, state, rt
    rt.session.close()
    hub.close()


json_values = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats(allow_nan=False) | st.text(max_size=8),
    lambda inner: st.lists(inner, max_size=3) | st.dictionaries(st.text(max_size=4), inner, max_size=3),
    max_leaves=6,
)
requests = st.fixed_dictionaries(
    {"op": st.sampled_from(["get", "set", "set", "list", ""]) | st.text(max_size=4)},
    optional={
        "key": st.sampled_from(["gain", "offset", "nope", ""]) | st.text(max_size=6),
        "value": json_values,
        "restart": st.booleans(),
    },
)


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(request=requests)
def test_any_request_is_answered_or_refused_with_a_reason_and_never_applies_an_invalid_value(runtime, request):
    *_, rt = runtime
    slot = rt.slots[0]
    before = slot.node.params
    try:
        answer = rt.live_params.handle(slot, request)
    except (ParamRefused, KeyError) as exc:  # KeyError: a set without a key (answered as a bad request)
        assert str(exc)
        assert slot.node.params is before
        return
    assert answer["ok"] and set(answer["live"]) == {"gain", "offset"}
    if request["op"] == "set":
        assert request["key"] in ("gain", "offset")
        expected = GainOffsetParams.model_validate({**dict(before), request["key"]: request["value"]})
        assert answer["params"] == expected.model_dump(mode="json")
        if answer.get("restart"):  # checked only: the launcher restarts the node with it
            assert request["restart"] and slot.node.params is before
        else:
            assert slot.node.params == expected
    else:
        assert slot.node.params is before


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    values=st.dictionaries(st.sampled_from(["gain", "offset", "nope"]) | st.text(max_size=4), json_values) | json_values
)
def test_several_values_at_once_are_checked_together_and_never_applied_by_the_node(runtime, values):
    """``param load --restart``: the node checks every value (the launcher restarts it with them once)."""
    *_, rt = runtime
    slot = rt.slots[0]
    before = slot.node.params
    try:
        answer = rt.live_params.handle(slot, {"op": "set", "values": values, "restart": True})
    except (ParamRefused, TypeError, ValueError) as exc:  # TypeError/ValueError: not a mapping (a bad request)
        assert str(exc) and slot.node.params is before
        return
    assert answer["ok"] and answer["restart"] and slot.node.params is before
    expected = GainOffsetParams.model_validate({**dict(before), **dict(values)})
    assert answer["params"] == expected.model_dump(mode="json")


def test_a_refused_value_names_the_key_and_the_models_message(runtime):
    *_, rt = runtime
    slot = rt.slots[0]
    with pytest.raises(ParamRefused, match=r"scale.gain = \"x\" refused: gain: Input should be a valid number"):
        rt.live_params.handle(slot, {"op": "set", "key": "gain", "value": "x"})
    with pytest.raises(ParamRefused, match="has no parameter 'gian'") as unknown:
        rt.live_params.handle(slot, {"op": "set", "key": "gian", "value": 1})
    assert unknown.value.code == 2


def test_a_node_hook_that_refuses_keeps_the_old_params(runtime, monkeypatch):
    *_, rt = runtime
    slot = rt.slots[0]
    before = slot.node.params

    def refuse(params, changed):
        slot.node.params = params  # half-way, then it finds the value unusable
        raise ValueError("calibration file missing")

    monkeypatch.setattr(slot.node, "on_params", refuse)
    with pytest.raises(ParamRefused, match="refused by the node: calibration file missing"):
        rt.live_params.handle(slot, {"op": "set", "key": "offset", "value": 7})
    assert slot.node.params is before


def test_the_nodes_next_process_starts_with_the_values_set_while_running(runtime):
    path, hub_ep, state, rt = runtime
    rt.live_params.handle(rt.slots[0], {"op": "set", "key": "offset", "value": 0.25})
    assert json.loads((state / "params-scale.json").read_text())["offset"] == 0.25
    again = GroupRuntime(load_graph(path), ["scale"], hub_ep, state_dir=state)  # a restart (or after a crash)
    try:
        assert again.slots[0].node.params.offset == 0.25
    finally:
        again.session.close()


@settings(max_examples=500, deadline=None)
@given(text=st.text(max_size=30) | st.dates().map(str))
def test_any_command_line_value_becomes_a_value_json_carries(text):
    """`handflow param set N.K VALUE`: VALUE from the command line is read as YAML, and what the request
    carries is always JSON; a date (which JSON cannot carry) or unreadable YAML stays the text."""
    from handflow.framework.commands.param import scalar

    json.dumps(scalar(text))


def test_command_line_values_are_yaml_scalars():
    from handflow.framework.commands.param import scalar

    assert [scalar(t) for t in ("3", "0.5", "null", "sine", "[1, 2]", "2026-11-28", "a: [")] == [
        3,
        0.5,
        None,
        "sine",
        [1, 2],
        "2026-11-28",
        "a: [",
    ]
