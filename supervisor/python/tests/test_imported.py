"""A network imported from a DBC file (`harvemu import`) as a python-can bus: its nodes send the
DBC's cyclic messages, laid out as the DBC says, and the program takes a node's place."""

import subprocess

import can
import pytest

# ENGINE sends EEC1 (29-bit, every 20 ms) with EngineSpeed starting at raw 12000 (1500 rpm at
# 0.125 rpm/bit, bytes 3..4 low byte first); BRAKE sends Brake (11-bit 0x100, every 100 ms),
# its Pressure starting at raw 0x1234 big-endian in bytes 0..1.
DBC = """VERSION ""

NS_ :

BS_:

BU_: ENGINE BRAKE

BO_ 2566844926 EEC1: 8 ENGINE
 SG_ EngineSpeed : 24|16@1+ (0.125,0) [0|8031.875] "rpm" BRAKE

BO_ 256 Brake: 2 BRAKE
 SG_ Pressure : 7|16@0+ (0.01,0) [0|655.35] "bar" ENGINE

BA_DEF_ BO_ "GenMsgCycleTime" INT 0 65535;
BA_DEF_ SG_ "GenSigStartValue" INT 0 65535;
BA_DEF_ "Baudrate" INT 0 1000000;
BA_DEF_DEF_ "GenMsgCycleTime" 0;
BA_DEF_DEF_ "GenSigStartValue" 0;
BA_DEF_DEF_ "Baudrate" 500000;
BA_ "Baudrate" 500000;
BA_ "GenMsgCycleTime" BO_ 2566844926 20;
BA_ "GenMsgCycleTime" BO_ 256 100;
BA_ "GenSigStartValue" SG_ 2566844926 EngineSpeed 12000;
BA_ "GenSigStartValue" SG_ 256 Pressure 4660;
"""


@pytest.fixture
def network(tmp_path, harvemu_bin):
    dbc = tmp_path / "truck.dbc"
    dbc.write_text(DBC)
    out = tmp_path / "truck"
    done = subprocess.run([harvemu_bin, "import", str(dbc), "--out", str(out)],
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    return out / "network.ron"


def test_an_imported_network_sends_its_dbc_messages_on_the_bus(network):
    with can.Bus(interface="harvemu", config=network, without=[], seed=1) as bus:
        assert bus.harvester.bitrate() == 500000
        got = [bus.recv(timeout=1.0) for _ in range(30)]
        eec1 = [m for m in got if m.is_extended_id and m.arbitration_id == 0x18FEF1FE]
        brake = [m for m in got if not m.is_extended_id and m.arbitration_id == 0x100]
        assert len(eec1) >= 20 and len(brake) >= 2
        assert bytes(eec1[0].data) == bytes([0, 0, 0, 0xE0, 0x2E, 0, 0, 0])
        assert bytes(brake[0].data) == bytes([0x12, 0x34])
        assert eec1[1].timestamp - eec1[0].timestamp == pytest.approx(0.020, abs=1e-3)


def test_the_program_takes_an_imported_nodes_place(network):
    with can.Bus(interface="harvemu", config=network, without=["BRAKE"], node="bench",
                 seed=1) as bus:
        got = [bus.recv(timeout=1.0) for _ in range(20)]
        assert not any(m.arbitration_id == 0x100 and not m.is_extended_id for m in got)
        bus.send(can.Message(arbitration_id=0x100, is_extended_id=False, data=[0x00, 0x64]))
        names = {name for name, *_ in bus.harvester.states()}
        assert {"ENGINE", "bench"} <= names and "BRAKE" not in names
