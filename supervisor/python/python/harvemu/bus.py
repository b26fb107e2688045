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


# The largest seed: harvemu draws from 64-bit seeds.
_SEED_MAX = 2**64 - 1


def _node_names(without):
    """``without`` as python-can's configs give it: a list of node names, or one string of names
    separated by commas (can.rc, ``--bus-kwargs``, ``CAN_CONFIG``)."""
    accepted = "node names, as a list (['F5', 'D3']) or one string ('F5,D3')"
    if isinstance(without, str):
        return [n.strip() for n in without.split(",") if n.strip()]
    try:
        names = list(without)
    except TypeError:
        raise can.CanInitializationError(f"without={without!r}: give {accepted}") from None
    for n in names:
        if not isinstance(n, str):
            raise can.CanInitializationError(
                f"without={without!r}: {n!r} is not a node name; give {accepted}")
    return names


def _seed(seed):
    """``seed`` checked: None, or a whole number harvemu can draw from."""
    if seed is None:
        return None
    if isinstance(seed, bool) or not isinstance(seed, int) or not 0 <= seed <= _SEED_MAX:
        raise can.CanInitializationError(
            f"seed={seed!r}: give a whole number from 0 to {_SEED_MAX}, or None for the "
            f"config's seed")
    return seed


def _checked_id(msg):
    """The message's identifier, if the frame it names can be sent (CAN 2.0B: 11 or 29 bits)."""
    if msg.is_fd:
        raise can.CanOperationError(
            "is_fd=True: the harvester's bus is CAN 2.0B (classic frames of at most 8 bytes); "
            "send the message with is_fd=False")
    limit = 0x1FFFFFFF if msg.is_extended_id else 0x7FF
    arbitration_id = msg.arbitration_id
    if isinstance(arbitration_id, bool) or not isinstance(arbitration_id, int) \
            or not 0 <= arbitration_id <= limit:
        kind = "an extended identifier (29 bits)" if msg.is_extended_id \
            else "a standard identifier (11 bits)"
        raise can.CanOperationError(
            f"arbitration_id={arbitration_id!r}: {kind} is from 0 to {limit:#x}")
    return arbitration_id


def _filter_specs(filters):
    """python-can's filter dicts as harvemu takes them: (can_id, can_mask, extended or None)."""
    specs = []
    for f in filters or []:
        try:
            can_id, can_mask = f["can_id"], f["can_mask"]
            extended = f.get("extended")
        except (TypeError, KeyError, AttributeError):
            raise can.CanOperationError(
                f"filter {f!r}: a filter is a dict with 'can_id' and 'can_mask' (and "
                f"'extended' if it matters)") from None
        for key, value in (("can_id", can_id), ("can_mask", can_mask)):
            if isinstance(value, bool) or not isinstance(value, int) \
                    or not 0 <= value <= 0x1FFFFFFF:
                raise can.CanOperationError(
                    f"filter {f!r}: {key} is a whole number from 0 to 0x1fffffff")
        if extended is not None and not isinstance(extended, bool):
            raise can.CanOperationError(f"filter {f!r}: extended is True, False or None")
        specs.append((can_id, can_mask, extended))
    return specs


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
        if kwargs.get("fd"):
            raise can.CanInitializationError(
                "fd=True: the harvester's bus is CAN 2.0B (classic frames of at most 8 bytes), "
                "not CAN FD")
        without = _node_names(without)
        seed = _seed(seed)
        try:
            self._harvester = Harvester(
                config=None if config is None else str(config),
                without=without,
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
        try:
            super().__init__(channel=channel, can_filters=can_filters, **kwargs)
        except can.CanOperationError as e:
            self._harvester.close()
            raise can.CanInitializationError(f"can_filters: {e}") from e

    @staticmethod
    def _detect_available_configs():
        """The one bus harvemu offers: the built-in harvester, the program in the monitor's
        place."""
        return [{"interface": "harvemu", "channel": "harv0"}]

    @property
    def harvester(self):
        """The harvester behind the bus."""
        return self._harvester

    def _apply_filters(self, filters):
        specs = _filter_specs(filters)
        try:
            self._harvester.set_filters(specs)
        except (ValueError, RuntimeError) as e:
            raise can.CanOperationError(str(e)) from e

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
        arbitration_id = _checked_id(msg)
        try:
            self._harvester.send(
                arbitration_id,
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
        try:
            return self._harvester.run_for(seconds)
        except (ValueError, RuntimeError) as e:
            raise can.CanOperationError(str(e)) from e

    def shutdown(self):
        super().shutdown()
        self._harvester.close()
