"""EEG trigger backends: parallel port, serial (BioSemi USB / Brain Products TriggerBox), LSL, file.

Each backend has ``set(code)`` (raise the lines / send the byte / push the marker) and
``reset()``. :class:`TriggerSender` logs every code with the time it was sent; the runner
calls :meth:`TriggerSender.send` from ``win.callOnFlip`` so the code goes out right after the
onset flip, and :meth:`TriggerSender.reset` after the pulse width.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path
from typing import Any, Protocol as TypingProtocol

from appeal.errors import AppealInputError
from experiments.protocol_schema import TriggerSpec

__all__ = ["TriggerBackend", "ParallelBackend", "SerialBackend", "LslBackend", "FileBackend",
           "TriggerSender", "open_backend"]


class TriggerBackend(TypingProtocol):
    """What a trigger device offers."""

    def set(self, code: int) -> None: ...
    def reset(self) -> None: ...
    def close(self) -> None: ...


class ParallelBackend:
    """A parallel port (``psychopy.parallel``), data lines set to the code, then 0."""

    def __init__(self, address: str):
        from psychopy import parallel

        try:
            self.port = parallel.ParallelPort(address=int(address, 0) if address.startswith("0x") else address)
        except Exception as exc:  # noqa: BLE001 - hardware errors come in many types
            raise AppealInputError(f"triggers.address: cannot open parallel port {address} ({exc})") from None

    def set(self, code: int) -> None:
        self.port.setData(int(code))

    def reset(self) -> None:
        self.port.setData(0)

    def close(self) -> None:
        self.reset()


class SerialBackend:
    """A serial trigger interface: one byte per code, a 0 byte to reset.

    Works with the BioSemi USB trigger interface and the Brain Products TriggerBox (both
    take the code as one byte); ``address`` may be a device or any pyserial URL
    (``loop://`` for a loop-back used in tests).
    """

    def __init__(self, address: str, baudrate: int = 115200, *, port: Any = None):
        import serial

        if port is not None:
            self.port = port
        else:
            try:
                self.port = serial.serial_for_url(address, baudrate=baudrate, timeout=0, write_timeout=0.01)
            except (serial.SerialException, ValueError) as exc:
                raise AppealInputError(f"triggers.address: cannot open serial port {address} ({exc})") from None

    def set(self, code: int) -> None:
        self.port.write(bytes([int(code)]))

    def reset(self) -> None:
        self.port.write(b"\x00")

    def close(self) -> None:
        self.port.close()


class LslBackend:
    """A Lab Streaming Layer marker stream (``pylsl``); markers are pushed, reset is a no-op."""

    def __init__(self, stream_name: str):
        import pylsl

        info = pylsl.StreamInfo(stream_name, "Markers", 1, pylsl.IRREGULAR_RATE, "int32", f"appeal-{stream_name}")
        self.outlet = pylsl.StreamOutlet(info)
        self._clock = pylsl.local_clock

    def set(self, code: int) -> None:
        self.outlet.push_sample([int(code)], self._clock())

    def reset(self) -> None:
        return None

    def close(self) -> None:
        del self.outlet


class FileBackend:
    """No hardware: every set/reset is appended to a TSV (code, time) and flushed."""

    def __init__(self, path: str | Path, clock: Callable[[], float]):
        self.path = Path(path)
        self.clock = clock
        new = not self.path.exists()
        self._fh = open(self.path, "a", encoding="utf-8")  # noqa: SIM115 - kept open for the session
        if new:
            self._fh.write("event\tcode\ttime_s\n")

    def _log(self, event: str, code: int) -> None:
        self._fh.write(f"{event}\t{code}\t{self.clock():.6f}\n")
        self._fh.flush()

    def set(self, code: int) -> None:
        self._log("set", code)

    def reset(self) -> None:
        self._log("reset", 0)

    def close(self) -> None:
        self._fh.close()


class TriggerSender:
    """Sends codes through a backend and remembers when (for the log and the report).

    Parameters
    ----------
    backend : TriggerBackend
        The device.
    clock : callable
        Returns the session time in seconds (the same clock flips are stamped with).
    """

    def __init__(self, backend: TriggerBackend, clock: Callable[[], float]):
        self.backend = backend
        self.clock = clock
        self.sent: list[tuple[int, float]] = []
        self.high = False

    def send(self, code: int) -> None:
        """Raise ``code`` now and record the time (called from ``win.callOnFlip``)."""
        self.backend.set(code)
        self.high = True
        self.sent.append((int(code), self.clock()))

    def reset(self) -> None:
        """Return the lines to 0 (no-op when already low)."""
        if self.high:
            self.backend.reset()
            self.high = False

    def close(self) -> None:
        """Reset and release the device."""
        self.reset()
        self.backend.close()


def open_backend(spec: TriggerSpec, *, log_path: Path, clock: Callable[[], float], simulate: bool) -> TriggerBackend:
    """Open the backend ``spec`` names; a simulated session always uses the file backend."""
    if simulate or spec.backend == "file":
        return FileBackend(log_path, clock)
    if spec.backend == "parallel":
        return ParallelBackend(str(spec.address))
    if spec.backend == "serial":
        return SerialBackend(str(spec.address), spec.baudrate)
    return LslBackend(spec.stream_name)


def perf_clock() -> float:
    """A monotonic clock in seconds (the default session clock)."""
    return time.perf_counter()
