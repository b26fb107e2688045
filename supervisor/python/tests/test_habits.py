"""python-can as its documentation uses it, against harvemu: log files written and read back in
every format, the player, MessageSync, send-only and recv(0) loops, can.logger --passive,
listen-only and own messages.

Expectations come from python-can's own readers and from harvemu's own trace of the same seed,
not from the interface under test.
"""

import pathlib
import signal
import subprocess
import sys
import time

import can
import pytest

D0_TO_F5 = 0x0601F5D0
# Every node of the built-in harvester but the monitor.
FIELD_NODES = ["E0", "A0", *(f"B{i}" for i in range(8)), *(f"C{i}" for i in range(4)),
               *(f"D{i}" for i in range(6))]


def first_frames(n, seed=2011, **kwargs):
    with can.Bus(interface="harvemu", without=["F5"], seed=seed, **kwargs) as bus:
        return [bus.recv(timeout=1.0) for _ in range(n)]


FORMATS = [".log", ".asc", ".blf", ".csv", ".trc", ".mf4"]


@pytest.mark.parametrize("suffix", FORMATS)
def test_every_log_format_python_can_writes_reads_back(tmp_path, suffix):
    if suffix == ".mf4":
        import asammdf  # noqa: F401  (the MF4 writer needs it: .ci/run installs it)
    frames = first_frames(300)
    path = tmp_path / f"bus{suffix}"
    with can.Logger(str(path)) as log:
        for m in frames:
            log(m)
    back = list(can.LogReader(str(path)))
    assert len(back) == len(frames)
    if suffix == ".asc":
        # python-can's ASCReader gives times from the file's first frame unless asked for
        # relative_timestamp=False (test_the_asc_python_writes_matches_harvemus_own_record).
        for m in back:
            m.timestamp += frames[0].timestamp
    # A TRC file keeps timestamps to 0.1 ms (its v2.1 format: milliseconds with one decimal,
    # counted from the file's start time).
    delta = 1e-4 if suffix == ".trc" else 1e-6
    for a, b in zip(frames, back):
        assert a.equals(b, timestamp_delta=delta, check_channel=False), (a, b)
    # Dated as harvemu's traces are: 2024-01-01, not 1970.
    assert time.gmtime(back[0].timestamp).tm_year == 2024


def test_a_log_file_plays_back_with_can_player(tmp_path):
    # Written by can.Logger from harvemu's own messages: the channel is the bus's name.
    path = tmp_path / "bus.log"
    with can.Logger(str(path)) as log:
        for m in first_frames(20):
            log(m)
    assert " harv0 " in path.read_text().splitlines()[0]
    # 1,000 frames of the program's own (F5 to D0), 0.1 ms apart: the player sends them all
    # without a recv, so only a send that runs the bus can get them out.
    many = tmp_path / "many.log"
    many.write_text("".join(f"({1704067200 + i * 0.0001:.6f}) harv0 18FF00F5#{i % 256:02X}\n"
                            for i in range(1000)))
    for f in (path, many):
        out = subprocess.run([sys.executable, "-m", "can.player", "-i", "harvemu", "-c", "harv0",
                              str(f)], capture_output=True, text=True, timeout=300)
        assert out.returncode == 0, out.stderr


def test_message_sync_replays_a_log_into_the_bus(tmp_path):
    path = tmp_path / "replay.log"
    path.write_text("".join(f"({1704067200 + i * 0.0002:.6f}) harv0 18FF00F5#{i % 256:02X}\n"
                            for i in range(200)))
    with can.Bus(interface="harvemu", without=["F5"], seed=1) as bus:
        for msg in can.MessageSync(can.LogReader(str(path)), timestamps=True, gap=0):
            bus.send(msg)
        bus.run_for(1.0)
        assert bus.harvester.sent() == 200


def test_a_send_only_loop_of_1000_frames_gets_them_all_out():
    with can.Bus(interface="harvemu", without=["F5"], seed=1) as bus:
        msg = can.Message(arbitration_id=0x18FF00F5, data=bytes(8))
        for _ in range(1000):
            bus.send(msg)
        # The first frame waited for the nodes' boot: the time relay at 0.5 s plus D5's 155 ms.
        assert bus.harvester.ready_time() == pytest.approx(0.655)
        bus.run_for(1.0)
        assert bus.harvester.sent() == 1000
        # An extended frame with 8 data bytes is at least 131 bits with intermission (ISO
        # 11898-1): 1,000 of them take at least 0.524 s at 250 kbit/s.
        assert bus.run_for(0) > 0.655 + 0.524


def test_a_full_queue_that_never_drains_raises_after_the_timeout():
    with can.Bus(interface="harvemu", without=["F5"], seed=1) as bus:
        bus.harvester.wait_ready()
        for n in FIELD_NODES:
            bus.harvester.act(f'Disconnect("{n}")')
        msg = can.Message(arbitration_id=0x18FF00F5, data=b"\x01")
        for _ in range(16):           # the program's transmit queue holds 16 frames
            bus.send(msg, timeout=0)
        before = bus.run_for(0)
        with pytest.raises(can.CanOperationError, match="transmit queue"):
            bus.send(msg, timeout=0.25)
        assert bus.run_for(0) == pytest.approx(before + 0.25, abs=1e-9)
        with pytest.raises(can.CanOperationError, match="timeout"):
            bus.send(msg, timeout=-1)


def test_a_recv_zero_poll_loop_moves_bus_time():
    with can.Bus(interface="harvemu", without=["F5"], seed=1,
                 can_filters=[{"can_id": D0_TO_F5, "can_mask": 0x1FFFFFFF}]) as bus:
        got, polls = [], 0
        while len(got) < 3 and polls < 100_000:
            polls += 1
            m = bus.recv(0)
            if m is not None:
                got.append(m)
        assert len(got) == 3, polls
        # D0 says it awaits calibration every 250 ms once booted (0.5 s + 120 ms).
        assert got[2].timestamp - got[1].timestamp == pytest.approx(0.25, abs=1e-3)


def test_the_asc_python_writes_matches_harvemus_own_record(tmp_path, monkeypatch, harvemu_bin):
    # ASC dates carry no time zone: python-can writes and reads them in local time.
    monkeypatch.setenv("TZ", "UTC")
    time.tzset()
    ours = tmp_path / "harvemu.asc"
    out = subprocess.run([harvemu_bin, "run", "--fast", "--for", "2s", "--seed", "5", "--record",
                          str(ours)], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    theirs = tmp_path / "python.asc"
    with can.Bus(interface="harvemu", without=[], seed=5) as bus, \
            can.Logger(str(theirs)) as log:
        # Bounded by bus time, not by the timestamps under test.
        while (m := bus.recv(timeout=1.0)) is not None and bus.run_for(0) < 2.0:
            log(m)
    a = list(can.ASCReader(str(ours), relative_timestamp=False))
    b = list(can.ASCReader(str(theirs), relative_timestamp=False))
    assert len(a) == len(b) > 500
    for x, y in zip(a, b):
        assert (x.arbitration_id, bytes(x.data), x.is_extended_id) == \
            (y.arbitration_id, bytes(y.data), y.is_extended_id)
    # python-can's writer dates the file by its first frame to the millisecond (its header's
    # precision) and counts every time from that frame in microseconds: the first frame within
    # a millisecond, every gap to the microsecond.
    assert abs(a[0].timestamp - b[0].timestamp) < 1e-3
    for x, y in zip(a, b):
        assert (x.timestamp - a[0].timestamp) == pytest.approx(y.timestamp - b[0].timestamp,
                                                               abs=1.5e-6)


def test_can_logger_passive_logs_without_acknowledging(tmp_path):
    path = tmp_path / "passive.log"
    proc = subprocess.Popen([sys.executable, "-m", "can.logger", "-i", "harvemu", "-c", "harv0",
                             "--passive", "-f", str(path)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and (not path.exists() or path.stat().st_size < 10_000):
        time.sleep(0.2)
    proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 0, err
    assert "not properly shut down" not in err, err
    lines = path.read_text().splitlines()
    assert len(lines) > 100 and all(" harv0 " in line for line in lines[:-1]), lines[:3]


def test_passive_the_program_acknowledges_nothing_and_still_receives():
    # D0 alone with the program: only the program can acknowledge D0's frames.
    alone = [n for n in FIELD_NODES if n != "D0"] + ["F5"]
    with can.Bus(interface="harvemu", without=alone, seed=1,
                 can_filters=[{"can_id": D0_TO_F5, "can_mask": 0x1FFFFFFF}]) as bus:
        bus.state = can.BusState.PASSIVE
        assert bus.state == can.BusState.PASSIVE
        with pytest.raises(can.CanOperationError, match="listen-only"):
            bus.send(can.Message(arbitration_id=0x18FF00F5, data=b"\x01"))
        bus.run_for(2.0)
        d0 = {n: (s, tec) for n, s, tec, _ in bus.harvester.states()}["D0"]
        # Unacknowledged, D0 counts ack errors up to error passive (ISO 11898-1: an error
        # passive transmitter's ack errors add nothing more) and keeps sending.
        assert d0 == ("error passive", 128), d0
        # Still received (a listen-only controller takes frames off the bus).
        assert bus.recv(timeout=1.0) is not None
        bus.state = can.BusState.ACTIVE
        assert bus.state == can.BusState.ACTIVE
        bus.run_for(2.0)
        # Acknowledged again: every frame D0 gets out takes one off its TEC (ISO 11898-1).
        d0 = {n: (s, tec) for n, s, tec, _ in bus.harvester.states()}["D0"]
        assert d0[1] < 128, d0
        with pytest.raises(can.CanOperationError, match="ACTIVE or"):
            bus.state = can.BusState.ERROR


def test_own_messages_come_back_with_is_rx_false():
    own = [{"can_id": 0x18FF00F5, "can_mask": 0x1FFFFFFF}]
    with can.Bus(interface="harvemu", without=["F5"], seed=1, receive_own_messages=True,
                 can_filters=own) as bus:
        msg = can.Message(arbitration_id=0x18FF00F5, data=b"\x01\x02")
        bus.send(msg)
        back = bus.recv(timeout=1.0)
        assert back is not None and back.is_rx is False and back.channel == "harv0"
        assert back.equals(msg, timestamp_delta=None, check_channel=False, check_direction=False)
    with can.Bus(interface="harvemu", without=["F5"], seed=1, can_filters=own) as bus:
        bus.send(can.Message(arbitration_id=0x18FF00F5, data=b"\x01\x02"))
        assert bus.recv(timeout=1.0) is None


def test_bitrate_start_time_and_node_are_python_cans_arguments():
    for bad in (500000, "500000", 250000.5, True):
        with pytest.raises(can.CanInitializationError, match="bitrate=.*250000"):
            can.Bus(interface="harvemu", bitrate=bad)
    with can.Bus(interface="harvemu", bitrate="250000") as bus:
        assert bus.harvester.bitrate() == 250000
    with can.Bus(interface="harvemu", bitrate=250000, seed=1,
                 start_time="2025-06-01T12:00:00Z") as bus:
        assert bus.recv(timeout=1.0).timestamp > 1748779200.0
    import datetime
    for start in (1748779200, datetime.datetime(2025, 6, 1, 12, tzinfo=datetime.timezone.utc)):
        with can.Bus(interface="harvemu", seed=1, start_time=start) as bus:
            assert bus.harvester.epoch() == 1748779200.0
    for bad in ("yesterday", -5, float("nan"), datetime.datetime(2025, 6, 1)):
        with pytest.raises(can.CanInitializationError, match="start_time"):
            can.Bus(interface="harvemu", start_time=bad)
    with can.Bus(interface="harvemu", without=["F5"], node="F5", seed=1) as bus:
        bus.run_for(1.0)
        names = [n for n, *_ in bus.harvester.states()]
        assert names.count("F5") == 1 and "program" not in names


NOTHING = [{"can_id": 0x1FFFFFFF, "can_mask": 0x1FFFFFFF}]


def test_own_error_frames_arrive_in_socketcans_encoding():
    # A filter nothing passes: error frames only (filters leave them alone, as in SocketCAN).
    with can.Bus(interface="harvemu", without=["F5"], seed=1, can_filters=NOTHING) as bus:
        bus.harvester.wait_ready()
        for n in FIELD_NODES:
            bus.harvester.act(f'Disconnect("{n}")')
        bus.send(can.Message(arbitration_id=0x18FF00F5, data=b"\x01"))
        first = bus.recv(timeout=1.0)
        # Nobody acknowledges: an ACK error while transmitting, TEC 8 (ISO 11898-1, 12.1.4
        # rule 3), as linux/can/error.h encodes it: CAN_ERR_PROT | CAN_ERR_ACK |
        # CAN_ERR_BUSERROR | CAN_ERR_CNT; data[2] CAN_ERR_PROT_TX, data[3] CAN_ERR_PROT_LOC_ACK,
        # data[6] TEC, data[7] REC.
        assert first.is_error_frame and not first.is_extended_id and first.dlc == 8
        assert first.arbitration_id == 0x08 | 0x20 | 0x80 | 0x200
        assert bytes(first.data) == bytes([0, 0, 0x80, 0x19, 0, 0, 8, 0])
        assert first.channel == "harv0.program"
        # The bus stopped there, at the first bit of the error flag.
        assert bus.run_for(0) == pytest.approx(first.timestamp - bus.harvester.epoch(), abs=1e-6)
    with can.Bus(interface="harvemu", without=["F5"], seed=1, error_frames="none",
                 can_filters=NOTHING) as bus:
        bus.harvester.wait_ready()
        for n in FIELD_NODES:
            bus.harvester.act(f'Disconnect("{n}")')
        bus.send(can.Message(arbitration_id=0x18FF00F5, data=b"\x01"))
        assert bus.recv(timeout=1.0) is None
    with pytest.raises(can.CanInitializationError, match="error_frames"):
        can.Bus(interface="harvemu", error_frames="some")


def test_every_controllers_error_frames_are_the_traces_error_frames(tmp_path, harvemu_bin):
    # configs/scenarios/bus_off.ron: every D2 frame corrupted from 10 s to 10.15 s.
    trace = tmp_path / "bus_off.log"
    out = subprocess.run([harvemu_bin, "scenario", "configs/scenarios/bus_off.ron", "--seed", "3",
                          "--record", str(trace)], capture_output=True, text=True, timeout=300,
                         cwd=pathlib.Path(__file__).parents[3])
    assert out.returncode == 0, out.stderr
    expected = []
    for line in trace.read_text().splitlines():
        stamp, channel, frame = line.split()
        can_id, data = frame.split("#")
        if int(can_id, 16) & 0x20000000 and float(stamp[1:-1]) < 1704067210.5:
            expected.append((stamp[1:-1], channel, int(can_id, 16) & 0x7FF, data))
    assert len(expected) > 32
    got = []
    with can.Bus(interface="harvemu", without=[], node="tester", error_frames="all", seed=3,
                 can_filters=NOTHING) as bus:
        bus.run_for(10.0)
        bus.harvester.act('BitErrors(target: Node("D2"), hits: Always, until_s: Some(10.15))')
        while bus.run_for(0) < 10.5:
            msg = bus.recv(timeout=0.1)
            if msg is not None and msg.channel != "harv0.tester":
                assert msg.is_error_frame
                got.append((f"{msg.timestamp:.6f}", msg.channel, msg.arbitration_id,
                            bytes(msg.data).hex().upper()))
    assert got == expected


def test_a_notifier_receives_while_the_main_thread_sends():
    own = [{"can_id": 0x18FF00F5, "can_mask": 0x1FFFFFFF}]
    with can.Bus(interface="harvemu", without=["F5"], seed=1, receive_own_messages=True,
                 can_filters=own) as bus:
        reader = can.BufferedReader()
        notifier = can.Notifier(bus, [reader], timeout=0.1)
        try:
            for i in range(100):
                bus.send(can.Message(arbitration_id=0x18FF00F5, data=bytes([i])))
            got = [reader.get_message(timeout=30.0) for _ in range(100)]
        finally:
            notifier.stop()
        # Every frame out, in the order sent, each back through the notifier's thread.
        assert [bytes(m.data)[0] for m in got if m is not None] == list(range(100))
        assert all(not m.is_rx for m in got)


def test_listen_only_recv_takes_the_bus_in_slices_and_gives_the_same_frames():
    def frames(passive, n=3000):
        with can.Bus(interface="harvemu", without=[], seed=4) as bus:
            if passive:
                bus.state = can.BusState.PASSIVE
            got = [bus.recv(timeout=1.0) for _ in range(n)]
            # The harvester stands at most one slice (0.1 s) ahead of what recv handed over.
            ahead = bus.run_for(0) - (got[-1].timestamp - bus.harvester.epoch())
            return [(m.timestamp, m.arbitration_id, bytes(m.data)) for m in got], ahead
    # Listen-only changes nothing on a bus without faults: the same frames at the same times.
    active, _ = frames(False)
    passive, ahead = frames(True)
    assert passive == active
    assert 0 <= ahead <= 0.2 + 1e-9, ahead
    with can.Bus(interface="harvemu", without=["F5"], seed=1,
                 can_filters=[{"can_id": D0_TO_F5, "can_mask": 0x1FFFFFFF}]) as bus:
        bus.state = can.BusState.PASSIVE
        first = bus.recv(timeout=2.0)
        # D0 awaits calibration and says so every 250 ms: nothing within 0.2 s of its frame,
        # then the next one 250 ms after it.
        assert bus.recv(timeout=0.2) is None
        second = bus.recv(timeout=1.0)
        assert second.timestamp - first.timestamp == pytest.approx(0.25, abs=1e-3)
        # Back to active: what the slices held comes first, in order.
        third = bus.recv(timeout=1.0)
        bus.state = can.BusState.ACTIVE
        fourth = bus.recv(timeout=1.0)
        assert first.timestamp < second.timestamp < third.timestamp < fourth.timestamp


def test_state_reads_error_while_the_programs_controller_is_bus_off():
    with can.Bus(interface="harvemu", without=["F5"], seed=1, can_filters=NOTHING) as bus:
        bus.harvester.wait_ready()
        assert bus.state == can.BusState.ACTIVE
        # Every frame with the program's identifier corrupted: 32 transmit errors in a row take
        # its TEC from 0 to 256, bus off (ISO 11898-1, 12.1.4 rules 3 and 10).
        bus.harvester.act('BitErrors(target: Id("18FF00F5"), hits: Always, until_s: None)')
        bus.send(can.Message(arbitration_id=0x18FF00F5, data=b"\x01"))
        while (m := bus.recv(timeout=1.0)) is not None and not m.arbitration_id & 0x40:
            pass
        assert m is not None and m.channel == "harv0.program", m     # CAN_ERR_BUSOFF
        assert bus.state == can.BusState.ERROR
        assert [s for n, s, *_ in bus.harvester.states() if n == "program"] == ["bus off"]
