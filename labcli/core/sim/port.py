"""What the simulated ports share: the rig their URL names, and a USB-serial bridge with nothing
on its modem lines.

Both ``sim://`` ports (the firmware model of :mod:`.protocol_sim`, the compiled firmware on
simavr of :mod:`.hil_port`) build their rig from the URL through the registry and keep it when
the port is reopened with the same URL: the rig is physical, reopening powers the board up
again, not the rig.  Their bridge takes any line settings, hands a write to the firmware at
once (so nothing waits to go out) and has no modem lines wired: CTS, DSR and CD read as
asserted, RI as not, and setting RTS, DTR or a break does nothing.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from serial.serialutil import PortNotOpenError, SerialBase, SerialException

from . import make_rig
from .url import rig_options


class SimulatedPort(SerialBase):
    """pyserial's ``SerialBase`` with the URL's rig and a simulated bridge.

    Each port class gives ``from_url`` (pyserial's name for it): the options its own URL form
    gives, checked.
    """

    from_url: Callable[[str], dict]

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        self.rig: Any = None
        self.options: dict = {}
        super().__init__(*args, **kwargs)  # opens the port when given one

    def _open_rig(self) -> dict:
        """Check the port may open, read its URL's options and have the rig they name (``self.rig``)."""
        if self.is_open:
            raise SerialException("Port is already open.")
        if self._port is None:
            raise SerialException("Port must be configured before it can be used.")
        opts = self.from_url(self._port)
        if self.rig is None or opts != self.options:
            self.rig = make_rig(
                opts["mode"],
                seed=opts["seed"],
                noise=opts["noise"],
                drift=opts["drift"],
                tau_s=opts["tau"],
                **rig_options(opts),
            )
        self.options = opts
        return opts

    def _reconfigure_port(self) -> None:
        # Baud rate, framing and flow control change nothing on a simulated bridge.
        pass

    def reset_output_buffer(self) -> None:
        if not self.is_open:
            raise PortNotOpenError()

    @property
    def out_waiting(self) -> int:
        if not self.is_open:
            raise PortNotOpenError()
        return 0

    def _update_break_state(self) -> None:
        pass

    def _update_rts_state(self) -> None:
        pass

    def _update_dtr_state(self) -> None:
        pass

    @property
    def cts(self) -> bool:
        return True

    @property
    def dsr(self) -> bool:
        return True

    @property
    def ri(self) -> bool:
        return False

    @property
    def cd(self) -> bool:
        return True
