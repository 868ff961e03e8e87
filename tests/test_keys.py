"""State keys (:mod:`kgarment.case.keys`): every kind and start tag formats and parses back,
and the strings run folders hold (metrics columns, state names, checkpoint keys) read as
the keys they were written from."""

import pytest

from kgarment.case.keys import (
    ENERGY,
    GAIN,
    RHO,
    TENSION,
    TERM,
    Kind,
    Start,
    StateKey,
    base_motion,
    checkpoint_key,
    early_motion,
    format_label,
    fraction_name,
    frame_motion,
    is_started,
    level_name,
    motion_column,
    motion_columns,
    parse_checkpoint_key,
    parse_column,
    parse_label,
    parse_state_name,
    split_wearer,
    started,
    state_column,
    state_columns,
    wearer_motion,
)

KEYS = [StateKey.of("arm_flexion.right", Kind.ON), StateKey.of("twist", Kind.OFF), StateKey.of("pull", Kind.NONE),
        StateKey.of("pull", Kind.LOCK, "twist"), StateKey.of("twist@0.33", Kind.LOCK, "pull"),
        StateKey.of("pull", Kind.SOLO, "upper_back"), StateKey.of("pull@alice", Kind.CUSTOM, "1,0,0.5"),
        StateKey.of("@rest", Kind.CUSTOM, "on:pull"), StateKey.of("flex", Kind.CUSTOM, "a+b")]


@pytest.mark.parametrize("key", KEYS, ids=lambda k: k.name)
def test_round_trip(key):
    assert parse_label(key.label) == (key.kind, key.clutch_set)
    assert StateKey.of(key.motion, key.kind, key.clutch_set) == key
    assert parse_state_name(key.name) == (key, ())
    assert parse_checkpoint_key(checkpoint_key(key)) == key
    for prefix in (RHO, ENERGY):
        assert parse_column(state_column(prefix, key)) == (prefix, key.motion, key.label)
    for start in Start:
        assert parse_state_name(started(key.name, start)) == (key, (start.value,))
        assert is_started(started(key.name, start), start)
    low = level_name(level_name(key.name, 2), 1, Start.FROM_FULL)  # a level tag is replaced
    assert low == f"{key.name}@level1@from-full" and parse_state_name(low) == (key, ("level1", "from-full"))


def test_every_kind_formats():
    assert {k.kind for k in KEYS} == set(Kind)
    assert [format_label(k) for k in (Kind.ON, Kind.OFF, Kind.NONE)] == ["on", "off", "none"]
    with pytest.raises(ValueError):
        format_label(Kind.LOCK)
    with pytest.raises(ValueError):
        format_label(Kind.CUSTOM, "solo:a")  # a solo label, not one of the caller's


def test_tuple_compatible():
    """The key is the tuple run folders and older callers use: dicts keyed by it are looked up
    with (motion, label), and it unpacks and sorts as one."""
    energy = {StateKey.on("a"): 3.0, StateKey.lock("a", "b"): 2.0}
    assert energy[("a", "on")] == 3.0 and energy[("a", "lock:b")] == 2.0
    motion, label = StateKey.solo("b", "x")
    assert (motion, label) == ("b", "solo:x") and StateKey.solo("b", "x")[1] == "solo:x"
    assert sorted([StateKey.off("b"), StateKey.on("a")]) == [("a", "on"), ("b", "off")]
    with pytest.raises(AttributeError):
        StateKey.on("a").motion = "b"  # frozen


def test_run_folder_strings():
    """The strings of a run folder's metrics rows and checkpoint (as tests/test_design_guard,
    test_design_pick and test_studio_app write and read them)."""
    row = {"iteration": 3, "area": 0.4, "unconverged_states": "a[on];a[lock:b];b[off]", "term[a]": 0.1,
           "gain[a]": 0.4, "term[b]": 0.2, "rho[flex:on]": 1.093, "rho[flex:off]": 0.009, "rho[ext:on]": 1.066,
           "rho[a:lock:b]": 0.5, "rho[twist@0.33:solo:x]": 0.7, "energy[a:lock:b]": 2.0,
           "tension[arm_flexion.right:upper_back]": 12.0}
    assert list(state_columns(row, RHO)) == [("flex", "on"), ("flex", "off"), ("ext", "on"), ("a", "lock:b"),
                                             ("twist@0.33", "solo:x")]
    assert [k.kind for k in state_columns(row, RHO)] == [Kind.ON, Kind.OFF, Kind.ON, Kind.LOCK, Kind.SOLO]
    assert state_columns(row, ENERGY) == {StateKey.lock("a", "b"): 2.0}
    assert state_columns(row, TENSION) == {("arm_flexion.right", "upper_back"): 12.0}
    assert motion_columns(row, TERM) == {"a": 0.1, "b": 0.2} and motion_columns(row, GAIN) == {"a": 0.4}
    assert all(state_column(RHO, k) in row for k in state_columns(row, RHO))
    assert motion_column(TERM, "a") == "term[a]" and parse_column("area") is None
    names = [parse_state_name(n)[0] for n in row["unconverged_states"].split(";")]
    assert [k.kind for k in names] == [Kind.ON, Kind.LOCK, Kind.OFF] and names[1].clutch_set == "b"
    assert parse_checkpoint_key("arm_flexion.right|lock:arm_extension.right") == \
        ("arm_flexion.right", "lock:arm_extension.right")
    with pytest.raises(ValueError):
        parse_state_name("no brackets")


def test_motion_names():
    assert wearer_motion("arms_raise", "alice") == "arms_raise@alice"
    assert split_wearer("arms_raise@alice") == ("arms_raise", "alice") and split_wearer("x") == ("x", None)
    assert early_motion("pull", 1 / 3) == "pull@0.33" and frame_motion("pull", 0.5) == "pull@0.500"
    assert base_motion("pull@0.33") == "pull" and base_motion("pull") == "pull"
    assert fraction_name("pull[on]", 0.25) == "pull[on]@0.25"
