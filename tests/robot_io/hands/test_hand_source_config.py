"""``[hand_source]`` as one table per kind (robot_io.hands.config): each kind validates its own keys
with its own defaults, a key of another kind is refused naming that kind, and a table written when
every kind's keys stood in one table still loads."""

from __future__ import annotations

import pytest
from pydantic import ValidationError

from robot_io.config import ControllerConfig
from robot_io.errors import explain
from robot_io.hands.config import HAND_SOURCES, NatNetSource


def hand_source(**table):
    return ControllerConfig.model_validate({"hand_source": table}).hand_source


def refusal(**table) -> str:
    with pytest.raises(ValidationError) as refused:
        hand_source(**table)
    return explain(refused.value)


def test_a_natnet_source_needs_its_server_and_rigid_body_only_and_streams_metres():
    source = hand_source(kind="natnet", natnet_server="192.168.1.20", natnet_rigid_body="hand")
    assert isinstance(source, NatNetSource)
    assert (source.units_to_m, source.natnet_command_port, source.resolve_timeout_s) == (1.0, 1510, 5.0)
    assert not hasattr(source, "vicon_port") and not hasattr(source, "lsl_stream_type")


@pytest.mark.parametrize(("key", "value", "message"), [
    ("vicon_server", "192.168.1.30",
     '[hand_source] vicon_server is a key of kind = "vicon", not of kind = "natnet"'),
    ("lsl_stream_name", "Vicon", '[hand_source] lsl_stream_name is a key of kind = "lsl", not of kind = '
                                 '"natnet"'),
    ("vicon_host", "192.168.1.30", '[hand_source] vicon_host is no key of kind = "natnet"; it reads like '
                                   'one of kind = "vicon", whose keys are vicon_server, vicon_port, '
                                   "vicon_subject, vicon_segment"),
])
def test_a_key_of_another_kind_is_refused_naming_the_kind_it_belongs_to(key, value, message):
    assert refusal(kind="natnet", natnet_server="192.168.1.20", natnet_rigid_body="hand",
                   **{key: value}).startswith(message)


@pytest.mark.parametrize(("table", "message"), [
    ({"kind": "natnet", "natnet_server": "h", "natnet_rigid_body": "hand", "resolve_timeout_s": 90},
     "hand_source.resolve_timeout_s = 90: must be a finite number in (0, 60] s"),
    ({"kind": "natnet", "natnet_server": "h", "natnet_rigid_body": "hand", "units_to_m": 0.001},
     'hand_source.units_to_m = 0.001 but NatNet streams metres: set units_to_m = 1.0 with kind = "natnet"'),
    ({"kind": "udp", "udp_port": 70000}, "hand_source.udp_port = 70000: Input should be less than or "
                                         "equal to 65535"),
    ({"kind": "optitrack"}, "[hand_source] kind = 'optitrack' is no hand source; the kinds are "
                            '"simulated", "lsl", "udp", "natnet", "vicon"'),
    ({"kind": "lsl", "lsl_stream_typ": "Mocap"}, "hand_source.lsl_stream_typ = 'Mocap': Extra inputs "
                                                 "are not permitted"),
])
def test_a_bad_value_names_its_field_and_range(table, message):
    assert refusal(**table) == message


def test_a_table_with_every_kinds_keys_at_their_defaults_loads_as_its_own_kind():
    """As written (and stored with every session) before each kind had a table of its own."""
    flat = {"kind": "lsl", "lsl_stream_type": "Mocap", "lsl_stream_name": "Vicon", "lsl_channels": [0, 1, 2],
            "udp_host": "0.0.0.0", "udp_port": 9870, "natnet_server": None, "natnet_local_address": None,
            "natnet_command_port": 1510, "natnet_rigid_body": None, "vicon_server": None,
            "vicon_port": 801, "vicon_subject": None, "vicon_segment": None, "units_to_m": 0.001,
            "rotation": [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            "translation": [0.0, 0.0, 0.0], "resolve_timeout_s": 5.0}
    source = hand_source(**flat)
    assert source.model_dump(mode="json") == HAND_SOURCES.own_keys(flat)
    assert "udp_port" not in HAND_SOURCES.own_keys(flat)


#: What each kind needs besides its defaults.
REQUIRED = {"natnet": {"natnet_server": "127.0.0.1", "natnet_rigid_body": "hand", "units_to_m": 1.0},
            "vicon": {"vicon_server": "127.0.0.1", "vicon_subject": "hand", "vicon_segment": "hand",
                      "units_to_m": 0.001}}


@pytest.mark.parametrize("kind", HAND_SOURCES)
def test_each_kind_round_trips_through_its_dump_and_keeps_the_calibration_when_the_kind_changes(kind):
    turned = ((0.0, -1.0, 0.0), (1.0, 0.0, 0.0), (0.0, 0.0, 1.0))
    lsl = hand_source(kind="lsl", rotation=turned, translation=(0.1, 0.2, 0.3))
    config = ControllerConfig(hand_source=lsl.as_kind(kind, **REQUIRED.get(kind, {})))
    assert (config.hand_source.kind, config.hand_source.rotation) == (kind, turned)
    assert ControllerConfig.model_validate(config.model_dump(mode="json")) == config
