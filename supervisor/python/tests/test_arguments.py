"""python-can's contract for arguments, as its configs and its users give them: every bad
argument raises python-can's own error with a text that names it and what would do, at
construction `CanInitializationError`, on a bus call `CanOperationError`; never a raw
OverflowError, TypeError, KeyError or ValueError."""

import can
import pytest

D0_TO_F5 = 0x0601F5D0


def states(bus):
    """Every controller on the bus once the time relay has powered the field nodes."""
    bus.run_for(1.0)
    return {name: state for name, state, _, _ in bus.harvester.states()}


def test_without_may_be_one_string_of_names_as_can_rc_gives_it():
    # "F5" as a string was split into the letters F and 5.
    with can.Bus(interface="harvemu", without="F5") as bus:
        assert "F5" not in states(bus)
    with can.Bus(interface="harvemu", without="F5, D3") as bus:
        left = states(bus)
        assert "F5" not in left and "D3" not in left and "D2" in left
    with can.Bus(interface="harvemu", without="") as bus:
        assert "F5" in states(bus)


@pytest.mark.parametrize("kwargs, named", [
    ({"without": [5]}, "without=[5]: 5 is not a node name"),
    ({"without": 5}, "without=5: give node names"),
    ({"seed": -1}, "seed=-1: give a whole number from 0 to 18446744073709551615"),
    ({"seed": 2**64}, "seed=18446744073709551616: give a whole number"),
    ({"seed": 1.5}, "seed=1.5: give a whole number"),
    ({"fd": True}, "fd=True: the harvester's bus is CAN 2.0B"),
    ({"can_filters": [{"can_id": 1}]}, "can_filters: filter {'can_id': 1}: a filter is a dict "
                                       "with 'can_id' and 'can_mask'"),
    ({"can_filters": [{"can_id": -1, "can_mask": 0}]}, "can_id is a whole number from 0"),
    ({"without": ["X9"]}, "X9"),
])
def test_a_bad_argument_at_construction_is_a_can_initialization_error(kwargs, named):
    with pytest.raises(can.CanInitializationError) as e:
        can.Bus(interface="harvemu", **kwargs)
    assert named in str(e.value)


@pytest.mark.parametrize("msg, named", [
    (can.Message(arbitration_id=-1, data=[1]), "arbitration_id=-1: an extended identifier"),
    (can.Message(arbitration_id=0x20000000, data=[1]), "arbitration_id=536870912"),
    (can.Message(arbitration_id=0x800, is_extended_id=False, data=[1]),
     "arbitration_id=2048: a standard identifier (11 bits) is from 0 to 0x7ff"),
    (can.Message(arbitration_id=D0_TO_F5, is_fd=True, data=[1]), "is_fd=True: the harvester's "
                                                                  "bus is CAN 2.0B"),
])
def test_a_frame_that_cannot_be_sent_is_a_can_operation_error(msg, named):
    with can.Bus(interface="harvemu") as bus:
        with pytest.raises(can.CanOperationError) as e:
            bus.send(msg)
        assert named in str(e.value)
        # The bus goes on.
        bus.send(can.Message(arbitration_id=D0_TO_F5, data=[1]))
        assert bus.recv(timeout=1.0) is not None


def test_bad_filters_later_are_a_can_operation_error():
    with can.Bus(interface="harvemu") as bus:
        for bad in ([{"can_mask": 0}], ["0x123"], [{"can_id": 1, "can_mask": 2, "extended": 1}]):
            with pytest.raises(can.CanOperationError):
                bus.set_filters(bad)


def test_after_shutdown_every_bus_call_is_a_can_operation_error():
    bus = can.Bus(interface="harvemu")
    bus.shutdown()
    for call in (lambda: bus.recv(0.1), lambda: bus.send(can.Message(arbitration_id=1)),
                 lambda: bus.run_for(1.0), lambda: bus.set_filters(None)):
        with pytest.raises(can.CanOperationError) as e:
            call()
        assert "closed" in str(e.value)


def test_detect_available_configs_gives_a_bus_that_opens():
    configs = can.detect_available_configs("harvemu")
    assert configs == [{"interface": "harvemu", "channel": "harv0"}]
    with can.Bus(**configs[0]) as bus:
        assert bus.recv(timeout=1.0) is not None
