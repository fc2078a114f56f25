"""The navigator status contract: stamps, the record's encoding, tolerant decoding (pure)."""

import pytest

from swarm_common.nav_status import (
    ERROR,
    OK,
    OUTCOMES,
    TERMINAL,
    WARN,
    NavState,
    NavStatusRecord,
    decode,
    encode,
    level_of,
)
from swarm_common.stamps import NS_PER_S, format_stamp, format_stamp_ns, parse_stamp

FULL = NavStatusRecord(
    state=NavState.HOLDING, goal_id="12.000000500", stamp_ns=13 * NS_PER_S + 100_000_000,
    goal=(1.25, -3.5, 1.5708), distance_remaining=4.2, navigation_time=0.75, recoveries=2,
    holding_time=3.125, goal_wait_timeouts=1, reason="")


@pytest.mark.parametrize(("sec", "nanosec", "text"), [
    (0, 0, "0.000000000"),
    (7, 5, "7.000000005"),
    (12, 500, "12.000000500"),
    (3, 999_999_999, "3.999999999"),
    (1_700_000_000, 120_000_000, "1700000000.120000000"),
])
def test_stamp_text_is_padded_to_nine_digits_and_parses_back(sec, nanosec, text):
    assert format_stamp(sec, nanosec) == text
    assert format_stamp_ns(sec * NS_PER_S + nanosec) == text
    assert parse_stamp(text) == sec * NS_PER_S + nanosec


@pytest.mark.parametrize("text", ["1.5", "1.0000000005", "-1.000000000", " 1.000000000",
                                  "1", ".000000001", "", "a.000000000", "1.00000000x",
                                  "١.000000000", None])
def test_malformed_stamp_parses_to_none(text):
    assert parse_stamp(text) is None


@pytest.mark.parametrize(("sec", "nanosec"), [(-1, 0), (0, -1), (0, NS_PER_S)])
def test_format_stamp_rejects_out_of_range(sec, nanosec):
    with pytest.raises(ValueError, match="stamp"):
        format_stamp(sec, nanosec)


def test_state_sets_and_levels():
    assert NS_PER_S == 1_000_000_000
    assert [s.value for s in NavState] == ["IDLE", "PLANNING", "DRIVING", "HOLDING",
                                           "RECOVERING", "SUCCEEDED", "ABORTED", "CANCELED"]
    assert OUTCOMES == (NavState.SUCCEEDED, NavState.ABORTED, NavState.CANCELED)
    assert TERMINAL == (NavState.IDLE, *OUTCOMES)
    assert (OK, WARN, ERROR) == (0, 1, 2)  # diagnostic_msgs/DiagnosticStatus levels
    levels = {s.value: level_of(s) for s in NavState}
    assert levels == {"IDLE": OK, "PLANNING": OK, "DRIVING": OK, "SUCCEEDED": OK,
                      "HOLDING": WARN, "RECOVERING": WARN, "CANCELED": WARN, "ABORTED": ERROR}


def test_encode_gives_the_documented_keys_in_order_and_formats():
    values = encode(FULL)
    assert list(values.items()) == [
        ("state", "HOLDING"), ("goal_id", "12.000000500"), ("stamp", "13.100000000"),
        ("goal_x", "1.250"), ("goal_y", "-3.500"), ("goal_yaw", "1.5708"),
        ("distance_remaining_m", "4.200"), ("navigation_time_s", "0.750"), ("recoveries", "2"),
        ("holding_time_s", "3.125"), ("goal_wait_timeouts", "1"), ("reason", "")]


def test_round_trip():
    assert decode(encode(FULL)) == FULL
    idle = NavStatusRecord(state=NavState.IDLE, stamp_ns=0, distance_remaining=0.0,
                           navigation_time=0.0, recoveries=0, holding_time=0.0,
                           goal_wait_timeouts=0)
    assert encode(idle)["stamp"] == "0.000000000" and "goal_x" not in encode(idle)
    assert decode(encode(idle)) == idle
    for state in NavState:
        assert decode(encode(NavStatusRecord(state=state))).state is state


def test_decode_is_tolerant_of_malformed_and_missing_values():
    values = {**encode(FULL), "distance_remaining_m": "x", "navigation_time_s": "nan",
              "recoveries": "-1", "holding_time_s": "inf", "goal_wait_timeouts": "2.9",
              "stamp": "13.1", "goal_yaw": "", "unknown_key": "ignored"}
    st = decode(values)
    assert (st.state, st.goal_id) == (NavState.HOLDING, "12.000000500")
    assert (st.distance_remaining, st.navigation_time, st.holding_time) == (None, None, None)
    assert (st.recoveries, st.goal_wait_timeouts) == (None, 2)  # a count: >= 0, truncated
    assert (st.stamp_ns, st.goal) == (None, None)
    assert decode({}) == NavStatusRecord(state=None)


def test_decode_state_falls_back_to_message_and_normalises():
    assert decode({}, message="DRIVING").state is NavState.DRIVING
    assert decode({"state": " succeeded "}, message="IDLE").state is NavState.SUCCEEDED
    assert decode({"state": "FLYING"}).state is None
    assert decode({"goal_id": " 7.000000000 "}).goal_id == "7.000000000"
