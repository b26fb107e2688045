"""Frames per second into a Python ``recv`` loop: harvemu's bus beside python-can's own virtual
bus, in one run, as ``harvemu bench --python`` reports them.

- ``python-virtual``: python-can's ``interface="virtual"``, two buses on one channel; a thread
  sends ``frames`` messages on one while the loop receives them on the other with
  ``recv(timeout=1.0)``, as a test that feeds its code through the virtual bus does.
- ``python-recv``: the whole harvester (the monitor too, seed 2011) with the program beside it;
  the loop receives ``frames`` frames with ``recv(timeout=1.0)``, the bus stopping at each, so
  that a ``send`` after a ``recv`` would go out at that frame's end.
- ``python-recv-passive``: the same with the program's controller listen-only
  (``bus.state = can.BusState.PASSIVE``): the harvester hands the bus over a slice at a time and
  computes the next while the loop works through this one.

``python -m harvemu.throughput FRAMES`` prints one JSON object per row.
"""

import json
import sys
import threading
import time

import can

SEED = 2011


def virtual(frames):
    """python-can's virtual bus: frames per second into the recv loop."""
    channel = f"harvemu-throughput-{time.monotonic_ns()}"
    sender = can.Bus(interface="virtual", channel=channel)
    receiver = can.Bus(interface="virtual", channel=channel)
    msg = can.Message(arbitration_id=0x0601F5D0, is_extended_id=True, data=bytes(8))

    def send_all():
        for _ in range(frames):
            sender.send(msg)

    producer = threading.Thread(target=send_all)
    try:
        started = time.perf_counter()
        producer.start()
        got = 0
        while got < frames and receiver.recv(timeout=1.0) is not None:
            got += 1
        wall = time.perf_counter() - started
    finally:
        producer.join()
        sender.shutdown()
        receiver.shutdown()
    return {"scenario": "python-virtual", "frames": got, "wall_seconds": wall,
            "frames_per_second": got / wall}


def harvemu(frames, passive):
    """harvemu's bus: frames per second into the recv loop."""
    with can.Bus(interface="harvemu", without=[], seed=SEED) as bus:
        if passive:
            bus.state = can.BusState.PASSIVE
        started = time.perf_counter()
        got = 0
        while got < frames and bus.recv(timeout=1.0) is not None:
            got += 1
        wall = time.perf_counter() - started
        reached = bus.run_for(0)
    return {"scenario": "python-recv-passive" if passive else "python-recv", "frames": got,
            "wall_seconds": wall, "frames_per_second": got / wall, "bus_seconds": reached}


def rows(frames):
    """The three rows, measured one after another in this process."""
    return [virtual(frames), harvemu(frames, False), harvemu(frames, True)]


if __name__ == "__main__":
    n = int(sys.argv[1]) if len(sys.argv) > 1 else 200_000
    for row in rows(n):
        print(json.dumps(row))
