"""The python-can interface ``harvemu``: the program stands on the emulated harvester's bus.

In virtual time (the default) bus time is harvemu's: it moves only inside ``recv`` and
``run_for``, so the same seed and the same calls give the same frames at the same times. With
``virtual_time=False`` the bus keeps to the wall clock and runs between calls, as a real one does.
Filters are applied inside harvemu, where the frames arrive, as a kernel applies a socket's
filters.
"""

import can
from can.broadcastmanager import ModifiableCyclicTaskABC, RestartableCyclicTaskABC

from ._harvemu import Harvester


def _parts(messages):
    return [
        (m.arbitration_id, bytes(m.data), m.is_extended_id, m.is_remote_frame, m.dlc)
        for m in messages
    ]


class BusTimeCyclicTask(ModifiableCyclicTaskABC, RestartableCyclicTaskABC):
    """Messages sent over and over in bus time, by the program's own node inside harvemu: the
    first at once, then one every ``period`` s of bus time, for ``duration`` s if given."""

    def __init__(self, harvester, messages, period, duration=None, autostart=True):
        super().__init__(messages, period)
        self._harvester = harvester
        self._duration = duration
        self._task = None
        if autostart:
            self.start()

    def start(self):
        if self._task is None:
            try:
                self._task = self._harvester.start_periodic(
                    _parts(self.messages), self.period, self._duration)
            except (ValueError, RuntimeError) as e:
                raise can.CanOperationError(str(e)) from e

    def stop(self):
        if self._task is not None:
            self._harvester.stop_periodic(self._task)
            self._task = None

    def modify_data(self, messages):
        super().modify_data(messages)
        if self._task is not None:
            self._harvester.modify_periodic(self._task, _parts(self.messages))


class HarvemuBus(can.BusABC):
    """The emulated harvester as a python-can bus.

    :param channel: the program's name on the bus (in traces and reports).
    :param config: a harvester config file; the built-in default when None.
    :param without: the nodes the program stands in for ("F5": the monitor).
    :param seed: the run's seed; the config's when None.
    :param virtual_time: True: bus time moves only inside ``recv`` and ``run_for``, and message
        timestamps are bus time in seconds from the start. False: the bus keeps to the wall
        clock, and timestamps are seconds since 1970, as ``time.time()`` gives them.
    """

    def __init__(self, channel="harv0", can_filters=None, config=None, without=("F5",),
                 seed=None, virtual_time=True, **kwargs):
        try:
            self._harvester = Harvester(
                config=None if config is None else str(config),
                without=list(without),
                seed=seed,
                name=str(channel),
                virtual_time=bool(virtual_time),
            )
        except ValueError as e:
            raise can.CanInitializationError(str(e)) from e
        except RuntimeError as e:
            raise can.CanInitializationError(str(e)) from e
        self.channel_info = f"harvemu {channel}"
        # Bus time zero on the wall clock, added to timestamps when the bus keeps to it.
        self._epoch = 0.0 if virtual_time else self._harvester.epoch()
        super().__init__(channel=channel, can_filters=can_filters, **kwargs)

    @property
    def harvester(self):
        """The harvester behind the bus."""
        return self._harvester

    def _apply_filters(self, filters):
        specs = []
        for f in filters or []:
            specs.append((int(f["can_id"]), int(f["can_mask"]), f.get("extended")))
        self._harvester.set_filters(specs)

    def recv(self, timeout=None):
        """The next frame that passes the filters, within ``timeout`` s of bus time (of the wall
        clock when the bus keeps to it)."""
        try:
            got = self._harvester.recv(timeout)
        except (ValueError, RuntimeError) as e:
            raise can.CanOperationError(str(e)) from e
        if got is None:
            return None
        t, arbitration_id, extended, remote, dlc, data = got
        return can.Message(
            timestamp=self._epoch + t,
            arbitration_id=arbitration_id,
            is_extended_id=extended,
            is_remote_frame=remote,
            dlc=dlc,
            data=None if remote else data,
            channel=self.channel_info,
            is_rx=True,
        )

    def send(self, msg, timeout=None):
        """Hands ``msg`` to the program's controller; it goes out when the bus next runs (at once
        when the bus keeps to the wall clock)."""
        try:
            self._harvester.send(
                msg.arbitration_id,
                bytes(msg.data),
                msg.is_extended_id,
                msg.is_remote_frame,
                msg.dlc,
            )
        except (ValueError, RuntimeError) as e:
            raise can.CanOperationError(str(e)) from e

    def _send_periodic_internal(self, msgs, period, duration=None, autostart=True,
                                modifier_callback=None):
        if modifier_callback is not None:
            raise can.CanOperationError(
                "harvemu sends periodic messages in bus time, inside the emulator: a "
                "modifier_callback cannot run there; change the data with the task's modify_data")
        return BusTimeCyclicTask(self._harvester, msgs, period, duration, autostart)

    def run_for(self, seconds):
        """Runs the harvester for ``seconds`` of bus time (waits for it when the bus keeps to
        the wall clock); the bus time reached, s."""
        return self._harvester.run_for(seconds)

    def shutdown(self):
        super().shutdown()
        self._harvester.close()
