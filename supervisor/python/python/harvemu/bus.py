"""The python-can interface ``harvemu``: the program stands on the emulated harvester's bus.

In virtual time (the default) bus time is harvemu's: it moves only inside the bus's calls
(``recv``, ``run_for``, ``harvester.wait_ready``, and a ``send`` that waits for the nodes' boot or
for room in the transmit queue), so the same seed and the same calls give the same frames at the
same times. With ``virtual_time=False`` the bus keeps to the wall clock and runs between calls, as
a real one does. Message timestamps are seconds since 1970 (bus time plus the start time);
``run_for`` and ``harvester.now()`` give bus time, seconds from 0.
Filters are applied inside harvemu, where the frames arrive, as a kernel applies a socket's
filters.
"""

import collections
import datetime
import math

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


def _check_timeout(timeout):
    """A bus call's ``timeout``: seconds (0 or more) or None."""
    if timeout is not None and not (isinstance(timeout, (int, float))
                                    and math.isfinite(timeout) and timeout >= 0):
        raise can.CanOperationError(f"timeout={timeout!r}: give seconds (0 or more) or None")


def _whole(value):
    """A whole number given as one or as its digits (as can.rc gives it), else None."""
    if isinstance(value, bool):
        return None
    if isinstance(value, int):
        return value
    if isinstance(value, str) and value.strip().isdigit():
        return int(value)
    return None


def _start_time(start_time):
    """``start_time`` as harvemu reads ``--start-time``: None, an RFC 3339 string, seconds since
    1970 (a number), or an aware ``datetime``."""
    if start_time is None:
        return None
    if isinstance(start_time, datetime.datetime):
        if start_time.tzinfo is None:
            raise can.CanInitializationError(
                f"start_time={start_time!r}: give a datetime with its time zone "
                f"(datetime.timezone.utc), so that the time is not a guess")
        return start_time.isoformat()
    if isinstance(start_time, str):
        return start_time
    if isinstance(start_time, (int, float)) and not isinstance(start_time, bool) \
            and math.isfinite(start_time) and start_time >= 0:
        t = datetime.datetime.fromtimestamp(start_time, datetime.timezone.utc)
        return t.isoformat()
    raise can.CanInitializationError(
        f"start_time={start_time!r}: give an RFC 3339 time ('2024-01-01T00:00:00Z'), seconds "
        f"since 1970, or a datetime with its time zone")


class HarvemuBus(can.BusABC):
    """The emulated harvester as a python-can bus.

    :param channel: the bus's name (``"harv0"``): every received message's ``channel``.
    :param config: a harvester config file; the built-in default when None.
    :param without: the nodes the program stands in for ("F5": the monitor).
    :param node: the program's node name on the bus (in traces, reports and
        ``harvester.states()``).
    :param seed: the run's seed; the config's when None.
    :param virtual_time: True: bus time moves only inside the bus's calls (see docs/PYTHON.md),
        the same seed and calls give the same frames at the same times. False: the bus keeps to
        the wall clock.
    :param start_time: where bus time zero lies, as ``harvemu run --start-time``: an RFC 3339
        time, seconds since 1970 or an aware datetime. By default 2024-01-01T00:00:00Z in
        virtual time (as harvemu's traces), the wall clock at the start otherwise. Message
        timestamps are seconds since 1970 from it.
    :param receive_own_messages: the program also receives the frames it sent, at their end of
        frame, with ``is_rx=False``.
    :param bitrate: checked against the harvester's (250 kbit/s); None takes it as it is.
    :param error_frames: whose error frames ``recv`` returns, as ``Message(is_error_frame=True)``
        in SocketCAN's encoding: ``"own"`` (the program's controller's, as a SocketCAN interface
        delivers its controller's), ``"all"`` (every controller's) or ``"none"``.
        ``ignore_rx_error_frames=True``, python-can's socketcan argument, is ``"none"``.
    """

    def __init__(self, channel="harv0", can_filters=None, config=None, without=("F5",),
                 seed=None, virtual_time=True, node="program", start_time=None,
                 receive_own_messages=False, bitrate=None, error_frames="own",
                 ignore_rx_error_frames=False, **kwargs):
        if kwargs.get("fd"):
            raise can.CanInitializationError(
                "fd=True: the harvester's bus is CAN 2.0B (classic frames of at most 8 bytes), "
                "not CAN FD")
        channel = "harv0" if channel is None else str(channel)
        if not isinstance(node, str) or not node:
            raise can.CanInitializationError(
                f"node={node!r}: give the program's node name, a string such as 'program'")
        without = _node_names(without)
        seed = _seed(seed)
        start = _start_time(start_time)
        if ignore_rx_error_frames:
            error_frames = "none"
        if error_frames not in ("own", "all", "none"):
            raise can.CanInitializationError(
                f"error_frames={error_frames!r}: give 'own' (the program's controller's), 'all' "
                f"(every controller's) or 'none'")
        try:
            self._harvester = Harvester(
                config=None if config is None else str(config),
                without=without,
                seed=seed,
                name=node,
                virtual_time=bool(virtual_time),
                start_time=start,
                own_frames=bool(receive_own_messages),
                error_frames=error_frames,
            )
        except (ValueError, RuntimeError) as e:
            raise can.CanInitializationError(str(e)) from e
        ours = self._harvester.bitrate()
        if bitrate is not None and _whole(bitrate) != ours:
            self._harvester.close()
            raise can.CanInitializationError(
                f"bitrate={bitrate!r}: the harvester's bus runs at {ours} bit/s; give "
                f"bitrate={ours} or leave it out")
        self.channel = channel
        self.channel_info = f"harvemu {channel}"
        self._listen_only = False
        self._virtual = bool(virtual_time)
        # Listen-only in virtual time, recv hands over the bus a slice at a time: the slices'
        # messages not handed over yet, the end of the last slice, and the bus time the program
        # has reached (the last message handed over, or the end of a recv's timeout).
        self._slices = collections.deque()
        self._slice_end = 0.0
        self._seen = 0.0
        self._longest_frame = 160 / self._harvester.bitrate()
        # Bus time zero, in seconds since 1970: message timestamps are counted from it.
        self._epoch = self._harvester.epoch()
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
        """The next frame that passes the filters, or error frame, within ``timeout`` s of bus
        time (of the wall clock when the bus keeps to it); frames and error frames in time
        order. Filters do not apply to error frames, as in SocketCAN."""
        if self._slices or (self._listen_only and self._virtual):
            got = self._sliced(timeout)
        else:
            try:
                got = self._harvester.recv(timeout)
            except (ValueError, RuntimeError) as e:
                raise can.CanOperationError(str(e)) from e
        return None if got is None else self._message(got)

    def _sliced(self, timeout):
        """recv listen-only in virtual time: the program changes nothing on the bus, so the
        harvester hands it over a slice of bus time at a time, computing the next while the
        program works through this one (docs/PYTHON.md, "State")."""
        if not (self._listen_only and self._virtual):
            return self._slices.popleft()       # left from listen-only: they came first
        _check_timeout(timeout)
        if timeout == 0:
            timeout = self._longest_frame       # as recv(0) runs the bus otherwise
        deadline = None if timeout is None else self._seen + timeout
        while True:
            if self._slices:
                t = self._slices[0][0]
                if deadline is not None and t > deadline:
                    self._seen = deadline
                    return None
                self._seen = t
                return self._slices.popleft()
            if deadline is not None and self._slice_end >= deadline:
                self._seen = deadline
                return None
            try:
                self._slice_end, items = self._harvester.slice()
            except (ValueError, RuntimeError) as e:
                raise can.CanOperationError(str(e)) from e
            self._slices.extend(items)

    def _message(self, got):
        t, arbitration_id, extended, remote, dlc, data, own, controller = got
        if controller is not None:
            # As python-can's socketcan interface gives an error frame: the flags off the
            # identifier, the classes left; on the controller's own interface, as in harvemu's
            # traces.
            return can.Message(
                timestamp=self._epoch + t,
                arbitration_id=arbitration_id & 0x7FF,
                is_extended_id=False,
                is_error_frame=True,
                dlc=dlc,
                data=data,
                channel=f"{self.channel}.{controller}",
                is_rx=True,
            )
        return can.Message(
            timestamp=self._epoch + t,
            arbitration_id=arbitration_id,
            is_extended_id=extended,
            is_remote_frame=remote,
            dlc=dlc,
            data=None if remote else data,
            channel=self.channel,
            is_rx=not own,
        )

    def send(self, msg, timeout=None):
        """Hands ``msg`` to the program's controller; it goes out when the bus next runs (at once
        when the bus keeps to the wall clock). In virtual time the first message waits until
        every node has booted, and while the transmit queue is full the bus runs until there is
        room, for at most ``timeout`` s of bus time (None: as long as it takes); then
        CanOperationError."""
        arbitration_id = _checked_id(msg)
        _check_timeout(timeout)
        try:
            queued = self._harvester.send(
                arbitration_id,
                bytes(msg.data),
                msg.is_extended_id,
                msg.is_remote_frame,
                msg.dlc,
                timeout,
            )
        except (ValueError, RuntimeError) as e:
            raise can.CanOperationError(str(e)) from e
        if not queued:
            raise can.CanOperationError(
                f"the transmit queue of the program's controller stayed full for "
                f"timeout={timeout!r} s of bus time: the message was not sent")

    @property
    def state(self):
        """ACTIVE, PASSIVE while the program's controller is in listen-only mode, ERROR while it
        is bus off."""
        try:
            _, state, _, _, listen_only = self._harvester.own()
        except (ValueError, RuntimeError) as e:
            raise can.CanOperationError(str(e)) from e
        if state == "bus off":
            return can.BusState.ERROR
        return can.BusState.PASSIVE if listen_only else can.BusState.ACTIVE

    @state.setter
    def state(self, new_state):
        """PASSIVE puts the program's controller in listen-only mode (it acknowledges and sends
        nothing, and still receives); ACTIVE takes it out. Listen-only in virtual time, recv
        takes the bus a slice of 0.1 s at a time, the harvester one slice ahead."""
        if new_state not in (can.BusState.ACTIVE, can.BusState.PASSIVE):
            raise can.CanOperationError(
                f"state={new_state!r}: set can.BusState.ACTIVE or can.BusState.PASSIVE")
        passive = new_state == can.BusState.PASSIVE
        try:
            self._harvester.set_listen_only(passive)
            if passive and not self._listen_only:
                self._seen = self._slice_end = self._harvester.now()
        except (ValueError, RuntimeError) as e:
            raise can.CanOperationError(str(e)) from e
        self._listen_only = passive

    def _send_periodic_internal(self, msgs, period, duration=None, autostart=True,
                                modifier_callback=None):
        if modifier_callback is not None:
            raise can.CanOperationError(
                "harvemu sends periodic messages in bus time, inside the emulator: a "
                "modifier_callback cannot run there; change the data with the task's modify_data")
        return BusTimeCyclicTask(self._harvester, msgs, period, duration, autostart)

    def run_for(self, seconds):
        """Runs the harvester for ``seconds`` of bus time (waits for it when the bus keeps to
        the wall clock); the bus time reached, s from 0 (a message's timestamp is that plus the
        start time, ``harvester.epoch()``)."""
        try:
            return self._harvester.run_for(seconds)
        except (ValueError, RuntimeError) as e:
            raise can.CanOperationError(str(e)) from e

    def shutdown(self):
        super().shutdown()
        self._harvester.close()
