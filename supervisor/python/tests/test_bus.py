"""The python-can interface `harvemu`, as a test engineer uses it.

Frames are written as docs/PROTOCOL.md gives them: identifiers are priority | type | destination
| source, so 0x0601F5D0 is flow sensor D0 (priority 6, type 1) to the monitor F5.
"""

import threading

import can
import pytest

D0_TO_F5 = 0x0601F5D0
REFERENCE_MARKER = bytes([0x20, 0x0E, 0x00, 0x02, 0xFF, 0xBE, 0xFF, 0x00])
# flow.calibrate (Data0 0x10): "start calibration" (1), target 10000 = 0x2710 low byte first,
# 5 reference groups.
START_CALIBRATION = bytes([0x10, 0x01, 0x10, 0x27, 0x05])


def monitorless(seed=2011, without=("F5",), **kwargs):
    return can.Bus(interface="harvemu", channel="harv0", without=list(without), seed=seed,
                   **kwargs)


def bus_time(bus, msg):
    """A message's bus time, s from the start: its timestamp counts from the start time."""
    return msg.timestamp - bus.harvester.epoch()


def only_d0():
    return [{"can_id": D0_TO_F5, "can_mask": 0x1FFFFFFF, "extended": True}]


def test_the_entry_point_gives_the_harvester_bus():
    with monitorless() as bus:
        assert type(bus).__name__ == "HarvemuBus"
        assert bus.channel_info == "harvemu harv0"
        msg = bus.recv(timeout=1.0)
        assert isinstance(msg, can.Message) and msg.is_extended_id and msg.is_rx
        # channel is the bus's name, as python-can's other interfaces have it.
        assert msg.channel == "harv0"


def test_recv_waits_in_bus_time_and_applies_the_filters():
    with monitorless() as bus:
        bus.set_filters([{"can_id": 0x1FFFFFFF, "can_mask": 0x1FFFFFFF, "extended": True}])
        assert bus.recv(timeout=2.5) is None
        assert bus.run_for(0) == 2.5
        bus.set_filters(only_d0())
        # D0 awaits its calibration and says so (flow.status, Data0 0x30) every 250 ms.
        a, b = bus.recv(timeout=1.0), bus.recv(timeout=1.0)
        assert (a.arbitration_id, a.data[0]) == (D0_TO_F5, 0x30)
        assert b.timestamp - a.timestamp == pytest.approx(0.25, abs=1e-3)
        # Bus time stopped where the frame ended; timestamps count from 2024-01-01T00:00:00Z,
        # as harvemu's traces.
        assert bus.harvester.epoch() == 1704067200.0
        assert bus.run_for(0) == pytest.approx(bus_time(bus, b), abs=1e-6)


def test_the_same_seed_and_calls_give_the_same_frames():
    def record(seed):
        with monitorless(seed) as bus:
            return [(m.timestamp, m.arbitration_id, bytes(m.data)) for m in
                    (bus.recv(timeout=1.0) for _ in range(500))]

    first = record(7)
    assert first == record(7)
    assert all(a[0] < b[0] for a, b in zip(first, first[1:]))
    assert first != record(8)


def test_what_the_program_sends_reaches_the_nodes():
    with monitorless() as bus:
        bus.set_filters(only_d0())
        bus.run_for(3.0)
        before = [bus.recv(timeout=1.0) for _ in range(8)]
        assert all(m is not None and bytes(m.data) != REFERENCE_MARKER for m in before)
        bus.send(can.Message(arbitration_id=0x0601D0F5, data=START_CALIBRATION))
        after = [bus.recv(timeout=0.5) for _ in range(8)]
        assert any(m is not None and bytes(m.data) == REFERENCE_MARKER for m in after)


def test_a_bad_config_raises_at_construction_with_file_and_line(tmp_path):
    bad = tmp_path / "bad.ron"
    bad.write_text('Harvester(\n    name: "x",\n    bitrate: "fast",\n)\n')
    with pytest.raises(can.CanInitializationError) as e:
        can.Bus(interface="harvemu", config=str(bad))
    assert "bad.ron:3" in str(e.value)
    with pytest.raises(can.CanInitializationError) as e:
        monitorless(without=["F5", "ZZ"])
    assert "ZZ" in str(e.value)


def test_a_frame_that_cannot_be_raises_can_operation_error():
    with monitorless() as bus:
        with pytest.raises(can.CanOperationError):
            bus.send(can.Message(arbitration_id=0x800, is_extended_id=False, data=b"\x01"))
        with pytest.raises(can.CanOperationError):
            bus.recv(timeout=-1.0)


def test_a_notifier_and_a_logger_work_in_bus_time(tmp_path):
    log = tmp_path / "harv.log"
    with monitorless() as bus:
        reader = can.BufferedReader()
        logger = can.Logger(str(log))
        notifier = can.Notifier(bus, [reader, logger], timeout=0.1)
        got = []
        while len(got) < 200:
            m = reader.get_message(timeout=10.0)
            assert m is not None, "the notifier's thread runs the bus"
            got.append(m)
        notifier.stop()
        logger.stop()
    assert all(a.timestamp <= b.timestamp for a, b in zip(got, got[1:]))
    lines = log.read_text().splitlines()
    assert len(lines) >= 200 and lines[0].startswith("(")


def test_calls_from_another_thread_are_served():
    with monitorless() as bus:
        out = []
        t = threading.Thread(target=lambda: out.append(bus.recv(timeout=1.0)))
        t.start()
        t.join(60)
        assert out and out[0] is not None


def test_the_example_of_docs_python_md_runs_as_it_stands(capsys):
    import pathlib
    import re
    doc = pathlib.Path(__file__).parents[3] / "docs" / "PYTHON.md"
    blocks = re.findall(r"```python\n(.*?)```", doc.read_text(), re.S)
    example = next(b for b in blocks if "reference groups" in b)
    exec(compile(example, str(doc), "exec"), {})
    out = capsys.readouterr().out
    m = re.fullmatch(r"(\d+) reference groups, (\d+) flow groups by ([\d.]+) s\n", out)
    assert m, out
    # D0 streams a flow group every 100 ms once running; calibration (five reference groups,
    # 100 ms apart) starts after the time relay powers it at 0.5 s: some 85 to 95 by 10 s.
    assert 80 <= int(m.group(2)) <= 100, out
    assert int(m.group(1)) >= 5, out


def test_the_scenario_example_of_docs_python_md_passes_as_it_stands():
    import pathlib
    import re
    doc = pathlib.Path(__file__).parents[3] / "docs" / "PYTHON.md"
    blocks = re.findall(r"```python\n(.*?)```", doc.read_text(), re.S)
    example = next(b for b in blocks if "def test_d2_bus_off" in b)
    scope = {}
    exec(compile(example, str(doc), "exec"), scope)
    scope["test_d2_bus_off_the_monitor_sees_it_silent_and_d2_comes_back"]()


def test_a_signal_ends_a_recv_that_would_wait_long():
    import os
    import signal

    class Stopped(Exception):
        pass

    def stop(signum, frame):
        raise Stopped()

    before = signal.signal(signal.SIGINT, stop)
    try:
        with monitorless() as bus:
            bus.set_filters([{"can_id": 0x1FFFFFFF, "can_mask": 0x1FFFFFFF, "extended": True}])
            threading.Timer(0.5, lambda: os.kill(os.getpid(), signal.SIGINT)).start()
            # Nothing passes and there is no timeout: 30 days of bus time, but for the signal.
            with pytest.raises(Stopped):
                bus.recv()
            # Stopped between two seconds of bus time; the bus is still there.
            assert 0 < bus.run_for(0) < 30 * 86400
    finally:
        signal.signal(signal.SIGINT, before)


def test_send_periodic_runs_in_bus_time():
    ack = can.Message(arbitration_id=0x0601D0F5, data=bytes([0x21, 0x0E, 0x01]))
    with monitorless() as bus:
        bus.run_for(3.0)
        # Every 100 ms for 1 s of bus time: at 3.0, 3.1, ... 3.9 s, ten frames, however long
        # that takes on the wall clock.
        task = bus.send_periodic(ack, 0.1, duration=1.0)
        bus.run_for(2.0)
        assert bus.harvester.sent() == 10
        task.stop()
        # Without a duration: until stopped (at 5.0, 5.1, ... 5.5 s).
        task = bus.send_periodic(ack, 0.1)
        bus.run_for(0.55)
        task.modify_data(can.Message(arbitration_id=0x0601D0F5, data=bytes([0x21, 0x0E, 0x02])))
        task.stop()
        bus.run_for(1.0)
        assert bus.harvester.sent() == 16
        with pytest.raises(can.CanOperationError):
            bus.send_periodic(ack, 0.1, modifier_callback=lambda m: None)


def test_node_states_the_monitors_display_and_plant_inputs():
    import json
    with monitorless() as bus:
        bus.run_for(2.0)
        states = bus.harvester.states()
        assert len(states) == 21 and ("program", "error active", 0, 0) in states
        assert bus.harvester.display() is None
        bus.harvester.set_input("operator.speed", 5.0)
        with pytest.raises(ValueError, match="operator.warp"):
            bus.harvester.set_input("operator.warp", 1.0)
    # With the monitor kept, the program is one more node beside it.
    with can.Bus(interface="harvemu", node="tester", without=[], seed=1) as bus:
        bus.run_for(1.0)
        shown = json.loads(bus.harvester.display())
        assert "phase" in shown


def test_faults_from_python_reach_the_program_as_on_a_bus():
    with monitorless() as bus:
        bus.set_filters(only_d0())
        bus.run_for(2.0)
        while bus.recv(timeout=0) is not None:
            pass
        # D0, disconnected, is silent; reconnected, heard again (its status every 250 ms).
        bus.harvester.act('Disconnect("D0")')
        assert bus.recv(timeout=1.0) is None
        bus.harvester.act('Reconnect("D0")')
        assert bus.recv(timeout=1.0) is not None
        # Every D0 frame destroyed by an error flag until a bus time, then heard again.
        until = round(bus.run_for(0) + 1.0)
        bus.harvester.act(f'BitErrors(target: Node("D0"), hits: Always, until_s: Some({until}.0))')
        # What arrives meanwhile is the program's controller's error frames (it detects each
        # error as a receiver): no frame of D0's.
        while (m := bus.recv(timeout=max(0.0, until - bus.run_for(0) - 0.001))) is not None:
            assert m.is_error_frame and m.channel == "harv0.program", m
            if bus.run_for(0) >= until - 0.001:
                break
        after = bus.recv(timeout=1.0)
        assert after is not None and bus_time(bus, after) > until
        with pytest.raises(ValueError, match="the action:1:"):
            bus.harvester.act("Disconnect(")
        with pytest.raises(ValueError, match="ZZ"):
            bus.harvester.act('Crash("ZZ")')


def test_a_python_monitor_keeps_all_six_sensors_streaming_for_ten_minutes():
    from harvemu import monitor

    first = monitor.run(600.0, seed=2011)
    second = monitor.run(600.0, seed=2011)
    # Byte for byte: every frame, every time stamp.
    assert first["digest"] == second["digest"]
    assert first["frames"] == second["frames"]
    for name, s in first["sensors"].items():
        # A flow group every 100 ms once running (docs/PROTOCOL.md); calibration takes about a
        # second after the time relay: some 5,985 groups in 600 s.
        assert 5900 <= s["flow_groups"] <= 6000, (name, s)
        # Awaiting calibration, calibrating, running; never "no acknowledgement" (4).
        assert s["states"] == [1, 2, 3], (name, s)
        assert s["flow_sum"] > 0, (name, s)


def test_with_virtual_time_false_the_bus_keeps_to_the_wall_clock():
    import time
    with monitorless(virtual_time=False, can_filters=only_d0()) as bus:
        assert bus.harvester.virtual_time is False
        reader = can.BufferedReader()
        notifier = can.Notifier(bus, [reader], timeout=0.1)
        # Sent from this thread while the notifier's thread waits in recv, once the field nodes
        # are up to acknowledge it (else the program's error frames would come first).
        bus.harvester.wait_ready()
        bus.send(can.Message(arbitration_id=0x18FF00F5, data=b"\x01\x02"))
        first = reader.get_message(timeout=30.0)
        assert first is not None and first.arbitration_id == D0_TO_F5
        # Stamped as time.time() stamps: the epoch is the wall clock at the start.
        assert abs(first.timestamp - time.time()) < 30
        sent = 0
        for _ in range(3000):
            sent = bus.harvester.sent()
            if sent:
                break
            time.sleep(0.01)
        assert sent == 1
        # The bus runs on between calls, never ahead of the wall clock.
        start = bus.harvester.now()
        wall = time.monotonic()
        time.sleep(0.3)
        later = bus.harvester.now()
        assert start < later <= start + (time.monotonic() - wall) + 0.01
        notifier.stop()
