"""The simulated rigs' sensors: from the rig's true values to the counts its ADC sends.

Every simulated rig reads its sensors through one :class:`SensorFrontEnd`, channel by
channel (:class:`SensorChannel`)::

    counts = clip(rint(transfer(value + offset) + drift(t) + noise), rails)

* ``transfer``: the sensor and the ADC, SI value -> ideal (unrounded) counts; the inverse
  of the channel's calibration (:class:`Linear`: ``value / gain + zero_counts``, as a
  protocol's ``[channels.NAME]`` table writes it), or a sensor that departs from it
  (:class:`GainLinearity`: its gain off by a few percent, its output bent off the straight
  line, as a potentiometer's datasheet states its independent linearity);
* ``offset``: the sensor's fixed error in SI (a pressure sensor's zero, a potentiometer
  mounted a little off), drawn by the rig;
* drift: a slow sinusoid per channel, ``drift * drift_counts * (sin(2 pi t / T + phi) -
  sin(phi))`` counts, zero at t = 0, with a seeded period T of 10-40 min and phase phi;
* noise: Gaussian, ``noise * noise_counts`` rms, from the rig's seeded generator;
* quantisation and rails: rounded to whole counts, held within the ADC's ``rails``.

``noise`` and ``drift`` scale every channel's figures at once (the ``sim://`` options of
the same names).  The front end draws from generators the rig hands it, in a fixed order,
so a seed gives the same counts every time.  A transducer's non-repeatability (a reading that
comes back elsewhere after an excursion, :func:`repeat_error`) depends on the rig's history,
so the rig adds it to the true value it hands over.
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


# Harmonics of a non-linearity's shape: a bow and an S over the span, the two shapes a
# potentiometer's deviation from its best line mostly takes.
LINEARITY_HARMONICS = 2
_GRID = np.linspace(0.0, 1.0, 2001)


@dataclass(frozen=True)
class GainLinearity:
    """A sensor whose reading departs from its nominal transfer ``inner``: ``inner(reading(v))``.

    ``reading(v) = v (1 + scale_error) + linearity * span * shape(v / span + 1/2)`` for values
    ``v`` (SI) about the middle of a range ``span`` wide: the gain is off by ``scale_error``
    (a potentiometer's effective electrical angle is not the nominal one the host calibrates
    with) and the output bends off the straight line by at most ``linearity`` of the span
    (the datasheet's independent linearity); ``shape`` is a sum of ``sin(h pi u)``, zero at
    both ends of the range, scaled to a largest magnitude of 1.
    """

    inner: Transfer
    span: float
    scale_error: float
    linearity: float
    coeffs: tuple[float, ...]

    @classmethod
    def seeded(
        cls, rng: np.random.Generator, inner: Transfer, span: float, scale_sd: float, linearity: float
    ) -> GainLinearity:
        """A scale error ~ N(0, ``scale_sd``) and a shape of its own (three draws)."""
        scale = float(scale_sd * rng.standard_normal())
        raw = rng.standard_normal(LINEARITY_HARMONICS)
        h = np.arange(1, LINEARITY_HARMONICS + 1)
        peak = float(np.abs(np.sin(np.pi * np.outer(_GRID, h)) @ raw).max())
        return cls(inner, float(span), scale, float(linearity), tuple(float(c) for c in raw / peak))

    def deviation(self, value: np.ndarray) -> np.ndarray:
        """The non-linearity alone at ``value`` (SI)."""
        u = np.asarray(value, dtype=float) / self.span + 0.5
        h = np.arange(1, LINEARITY_HARMONICS + 1)
        return self.linearity * self.span * (np.sin(np.pi * u[..., None] * h) @ np.asarray(self.coeffs))

    def reading(self, value: np.ndarray) -> np.ndarray:
        """The value as the host reads it through the nominal calibration (SI)."""
        v = np.asarray(value, dtype=float)
        return v * (1.0 + self.scale_error) + self.deviation(v)

    def slope(self, value: np.ndarray, step: float = 1e-6) -> np.ndarray:
        """``d reading / d value``: 1 plus the scale error a small change at ``value`` sees."""
        v = np.asarray(value, dtype=float)
        return (self.reading(v + step) - self.reading(v - step)) / (2 * step)

    def __call__(self, value: np.ndarray) -> np.ndarray:
        return self.inner(self.reading(value))


def repeat_error(rng: np.random.Generator, sd: float, k: int) -> np.ndarray:
    """One new reading's non-repeatability on each of ``k`` transducers (SI, N(0, ``sd``));
    zeros, without drawing, when ``sd`` is 0."""
    if not sd:
        return np.zeros(k)
    return sd * rng.standard_normal(k)


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
