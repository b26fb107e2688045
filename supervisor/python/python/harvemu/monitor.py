"""A monitor for the six flow sensors, in Python: the example docs/PYTHON.md builds on, the
pytest that keeps the sensors streaming for ten minutes of bus time, and the speed that
``python -m harvemu.monitor`` measures.

What it does is docs/PROTOCOL.md's flow-sensor exchange: it starts a sensor's calibration when
the sensor says it awaits one, acknowledges every complete group (marker and two parts), accepts
the calibration after five reference groups, answers "no acknowledgement" with "accept and
run", and sums the flow units of every flow group (the light the cotton in the duct blocks).
"""

import hashlib
import json
import sys
import time

import can

TARGET, SAMPLES = 10000, 5
SENSORS = range(0xD0, 0xD6)


def _to(sensor, *data):
    # Priority 6, type 1, destination the sensor, source the monitor F5.
    return can.Message(arbitration_id=0x06010000 | sensor << 8 | 0xF5, data=bytes(data))


class Sensor:
    def __init__(self):
        self.group = None
        self.parts = []
        self.acked = 0
        self.references = 0
        self.flow_groups = 0
        self.flow_sum = 0
        self.states = set()


def run(seconds, seed=2011):
    """Runs the harvester for ``seconds`` of bus time with this monitor in F5's place."""
    sensors = {s: Sensor() for s in SENSORS}
    digest = hashlib.sha256()
    frames = 0
    started = time.perf_counter()
    with can.Bus(interface="harvemu", without=["F5"], node="F5", seed=seed) as bus:
        # Timestamps are seconds since 1970; bus time is counted from the start time.
        start = bus.harvester.epoch()
        # Flow sensors to F5: priority 6, type 1, destination F5, sources D0 to D7.
        bus.set_filters([{"can_id": 0x0601F5D0, "can_mask": 0x1FFFFFF8, "extended": True}])
        while True:
            msg = bus.recv(timeout=1.0)
            if msg is None or msg.timestamp - start > seconds:
                break
            if msg.is_error_frame:                 # none on a bus without faults
                continue
            frames += 1
            d = bytes(msg.data)
            digest.update(msg.timestamp.hex().encode() + msg.arbitration_id.to_bytes(4, "big") + d)
            source = msg.arbitration_id & 0xFF
            s = sensors.get(source)
            if s is None:
                continue
            if d[0] == 0x30:                       # flow.status
                s.states.add(d[1])
                if d[1] == 1:                      # awaiting calibration: start it
                    bus.send(_to(source, 0x10, 0x01, TARGET & 0xFF, TARGET >> 8, SAMPLES))
                elif d[1] == 4:                    # no acknowledgement: accept and run
                    bus.send(_to(source, 0x10, 0x02, TARGET & 0xFF, TARGET >> 8, SAMPLES))
            elif d[0] == 0x20:                     # a marker: 0x0D flow, 0x0E reference
                s.group, s.parts = d[1], []
            elif d[0] in (0x01, 0x02) and s.group is not None:
                s.parts.append(d)
                if len(s.parts) == 2:              # a complete group: acknowledge it
                    s.acked += 1
                    bus.send(_to(source, 0x21, s.group, s.acked % 256))
                    if s.group == 0x0E:
                        s.references += 1
                        if s.references == SAMPLES:
                            bus.send(_to(source, 0x10, 0x02, TARGET & 0xFF, TARGET >> 8, SAMPLES))
                    else:
                        p1, p2 = s.parts
                        units = [p1[2:4], p1[4:6], p1[6:8], p2[1:3], p2[3:5]]
                        s.flow_groups += 1
                        s.flow_sum += sum(int.from_bytes(u, "little") for u in units)
                    s.group = None
        reached = bus.run_for(0)
    wall = time.perf_counter() - started
    return {
        "bus_seconds": reached,
        "wall_seconds": wall,
        "frames": frames,
        "speedup": reached / wall,
        "us_per_frame": wall * 1e6 / max(frames, 1),
        "digest": digest.hexdigest(),
        "sensors": {
            f"D{s - 0xD0}": {
                "flow_groups": v.flow_groups,
                "references": v.references,
                "flow_sum": v.flow_sum,
                "states": sorted(v.states),
            }
            for s, v in sensors.items()
        },
    }


if __name__ == "__main__":
    seconds = float(sys.argv[1]) if len(sys.argv) > 1 else 600.0
    print(json.dumps(run(seconds)))
