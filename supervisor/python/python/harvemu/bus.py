"""The python-can interface ``harvemu``: the program stands on the emulated harvester's bus.

Bus time is harvemu's: it moves only inside ``recv`` and ``run_for``, so the same seed and the
same calls give the same frames at the same times. Filters are applied inside harvemu, where the
frames arrive, as a kernel applies a socket's filters.
"""

import can

from ._harvemu import Harvester


class HarvemuBus(can.BusABC):
    """The emulated harvester as a python-can bus.

    :param channel: the program's name on the bus (in traces and reports).
    :param config: a harvester config file; the built-in default when None.
    :param without: the nodes the program stands in for ("F5": the monitor).
    :param seed: the run's seed; the config's when None.
    """

    def __init__(self, channel="harv0", can_filters=None, config=None, without=("F5",),
                 seed=None, **kwargs):
        try:
            self._harvester = Harvester(
                config=None if config is None else str(config),
                without=list(without),
                seed=seed,
                name=str(channel),
            )
        except ValueError as e:
            raise can.CanInitializationError(str(e)) from e
        except RuntimeError as e:
            raise can.CanInitializationError(str(e)) from e
        self.channel_info = f"harvemu {channel}"
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
        """The next frame that passes the filters, within ``timeout`` s of bus time."""
        try:
            got = self._harvester.recv(timeout)
        except (ValueError, RuntimeError) as e:
            raise can.CanOperationError(str(e)) from e
        if got is None:
            return None
        t, arbitration_id, extended, remote, dlc, data = got
        return can.Message(
            timestamp=t,
            arbitration_id=arbitration_id,
            is_extended_id=extended,
            is_remote_frame=remote,
            dlc=dlc,
            data=None if remote else data,
            channel=self.channel_info,
            is_rx=True,
        )

    def send(self, msg, timeout=None):
        """Hands ``msg`` to the program's controller; it goes out when the bus next runs."""
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

    def run_for(self, seconds):
        """Runs the harvester for ``seconds`` of bus time; the bus time reached, s."""
        return self._harvester.run_for(seconds)

    def shutdown(self):
        super().shutdown()
        self._harvester.close()
