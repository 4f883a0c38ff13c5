"""The simulated rigs' sensors: from the rig's true values to the counts its ADC sends.

Every simulated rig reads its sensors through one :class:`SensorFrontEnd`, channel by
channel (:class:`SensorChannel`)::

    counts = clip(rint(transfer(value + offset) + drift(t) + noise), rails)

* ``transfer``: the sensor and the ADC, SI value -> ideal (unrounded) counts; the inverse
  of the channel's calibration (:class:`Linear`: ``value / gain + zero_counts``, as a
  protocol's ``[channels.NAME]`` table writes it);
* ``offset``: the sensor's fixed error in SI (a pressure sensor's zero, a potentiometer
  mounted a little off), drawn by the rig;
* drift: a slow sinusoid per channel, ``drift * drift_counts * (sin(2 pi t / T + phi) -
  sin(phi))`` counts, zero at t = 0, with a seeded period T of 10-40 min and phase phi;
* noise: Gaussian, ``noise * noise_counts`` rms, from the rig's seeded generator;
* quantisation and rails: rounded to whole counts, held within the ADC's ``rails``.

``noise`` and ``drift`` scale every channel's figures at once (the ``sim://`` options of
the same names).  The front end draws from generators the rig hands it, in a fixed order,
so a seed gives the same counts every time.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

# Drift periods are drawn from this range (s): slower than any trial, faster than a day's run.
DRIFT_PERIOD_S = (600.0, 2400.0)

Transfer = Callable[[np.ndarray], np.ndarray]


@dataclass(frozen=True)
class Linear:
    """A linear sensor behind the ADC: ``counts = value / gain + zero_counts``.

    ``gain``: SI unit per count; ``zero_counts``: the count that reads 0.  The inverse of a
    protocol channel's calibration ``value = gain * (counts - zero_counts)``.
    """

    gain: float
    zero_counts: float

    def __call__(self, value: np.ndarray) -> np.ndarray:
        return np.asarray(value, dtype=float) / self.gain + self.zero_counts

    def to_si(self, counts: np.ndarray) -> np.ndarray:
        """The calibration: counts back to the SI value."""
        return (np.asarray(counts, dtype=float) - self.zero_counts) * self.gain


@dataclass(frozen=True)
class SensorChannel:
    """One channel of a simulated rig: its sensor's transfer, noise, drift and fixed error.

    ``noise_counts``: rms noise at ``noise = 1``; ``drift_counts``: the drift's amplitude at
    ``drift = 1``; ``offset``: added to the true value (SI) before the transfer.
    """

    name: str
    transfer: Transfer
    noise_counts: float = 0.0
    drift_counts: float = 0.0
    offset: float = 0.0


class SensorFrontEnd:
    """The sensors and ADC of a simulated rig (see the module's docstring).

    ``drift_rng`` gives each channel its drift period and phase (two draws of ``k`` values,
    taken here, whether or not the rig drifts); ``noise_rng`` the noise of every sample.
    """

    def __init__(
        self,
        channels: Sequence[SensorChannel],
        *,
        noise: float,
        drift: float,
        noise_rng: np.random.Generator,
        drift_rng: np.random.Generator,
        rails: tuple[int, int] = (0, 4095),
    ) -> None:
        if noise < 0 or drift < 0:
            raise ValueError("noise and drift must be >= 0")
        self.channels = tuple(channels)
        self.noise = float(noise)
        self.drift = float(drift)
        self.rails = rails
        k = len(self.channels)
        self.noise_sd_counts = np.array([c.noise_counts for c in self.channels], dtype=float)
        self.drift_counts = np.array([c.drift_counts for c in self.channels], dtype=float)
        self.drift_period_s = drift_rng.uniform(*DRIFT_PERIOD_S, k)
        self.drift_phase = drift_rng.uniform(0.0, 2 * np.pi, k)
        self._noise_rng = noise_rng

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(c.name for c in self.channels)

    def drift_at(self, t: np.ndarray) -> np.ndarray:
        """Each channel's zero drift (counts) at times ``t`` (s): shape ``(n, k)``."""
        tt = np.asarray(t, dtype=float)[:, None]
        return (
            self.drift
            * self.drift_counts
            * (np.sin(2 * np.pi * tt / self.drift_period_s + self.drift_phase) - np.sin(self.drift_phase))
        )

    def ideal_counts(self, values: np.ndarray, t: np.ndarray) -> np.ndarray:
        """Noise-free, unrounded counts ``(n, k)`` for true values ``(n, k)`` (SI) at times ``t``."""
        values = np.asarray(values, dtype=float)
        out = np.empty(values.shape)
        for j, c in enumerate(self.channels):
            out[:, j] = c.transfer(values[:, j] + c.offset)
        if self.drift:
            out += self.drift_at(t)
        return out

    def read(self, values: np.ndarray, t: np.ndarray) -> np.ndarray:
        """What the ADC sends for true values ``(n, k)`` at times ``t``: int64 counts ``(n, k)``.

        Noise is drawn for every sample even where the rails clip it, so the stream of draws
        depends only on how many samples were read.
        """
        x = self.ideal_counts(values, t)
        if self.noise:
            x = x + self.noise * self.noise_sd_counts * self._noise_rng.standard_normal(x.shape)
        lo, hi = self.rails
        return np.clip(np.rint(x), lo, hi).astype(np.int64)
