"""Underwater acoustic channel physics: absorption, path loss, noise, SNR, bit and frame errors.

Frequencies in kHz, ranges in metres, levels in dB (re 1 uPa, per Hz for spectral densities).
References: Thorp's absorption and the empirical noise spectra as used by M. Stojanovic, "On the
relationship between capacity and distance in an underwater acoustic communication channel"
(ACM SIGMOBILE MC2R 11(4), 2007), eqs. (1)-(7), after R. Coates, "Underwater Acoustic Systems"
(1989); spreading after R. Urick, "Principles of Underwater Sound"; bit error rates of binary
modulations in AWGN after J. Proakis, "Digital Communications". docs/acoustic.md shows them.
"""

from __future__ import annotations

import math

import numpy as np

from common.config.acoustic import AcousticMedium, Modulation

_BAND_POINTS = 33  # noise integrated over the band on this many frequencies


def thorp_absorption_db_per_km(f_khz: float) -> float:
    """Thorp's absorption coefficient (dB/km) at f kHz (Stojanovic 2007, eq. (3))."""
    f2 = f_khz * f_khz
    return 0.11 * f2 / (1.0 + f2) + 44.0 * f2 / (4100.0 + f2) + 2.75e-4 * f2 + 0.003


def transmission_loss_db(range_m: float, f_khz: float, k: float) -> float:
    """Path loss 10 log A(l, f) = k 10 log l + l a(f) (eq. (1)-(2)), l from 1 m (the
    source level's reference), absorption over the range in km."""
    r = max(range_m, 1.0)
    return k * 10.0 * math.log10(r) + (r / 1000.0) * thorp_absorption_db_per_km(f_khz)


def noise_psd_db(f_khz: float, shipping: float, wind_mps: float) -> float:
    """Ambient noise power spectral density (dB re 1 uPa per Hz) at f kHz: turbulence,
    shipping (activity 0..1), wind-driven waves and thermal noise, added as powers
    (Stojanovic 2007, eq. (7))."""
    lf = math.log10(f_khz)
    turbulence = 17.0 - 30.0 * lf
    ships = 40.0 + 20.0 * (shipping - 0.5) + 26.0 * lf - 60.0 * math.log10(f_khz + 0.03)
    wind = 50.0 + 7.5 * math.sqrt(wind_mps) + 20.0 * lf - 40.0 * math.log10(f_khz + 0.4)
    thermal = -15.0 + 20.0 * lf
    return 10.0 * math.log10(sum(10.0 ** (x / 10.0) for x in (turbulence, ships, wind, thermal)))


def band_noise_db(m: AcousticMedium) -> float:
    """Noise power (dB re 1 uPa) in the modem's band: the spectral density integrated over
    [f - B/2, f + B/2] (trapezoids on a fixed grid)."""
    lo = m.frequency_khz - m.bandwidth_khz / 2.0
    hi = m.frequency_khz + m.bandwidth_khz / 2.0
    f = np.linspace(lo, hi, _BAND_POINTS)
    psd = np.array([10.0 ** (noise_psd_db(x, m.shipping, m.wind_mps) / 10.0) for x in f])
    power = float(np.trapezoid(psd, f * 1000.0))  # per Hz, over Hz
    return 10.0 * math.log10(power)


def snr_db(m: AcousticMedium, range_m: float, noise_db: float | None = None) -> float:
    """Received signal-to-noise ratio (dB) over the band at range_m: SL - TL - noise."""
    n = band_noise_db(m) if noise_db is None else noise_db
    return m.source_level_db - transmission_loss_db(range_m, m.frequency_khz, m.spreading_k) - n


def bit_error_rate(modulation: Modulation, ebn0: float) -> float:
    """Bit error probability in AWGN at a linear Eb/N0 (Proakis): coherent BPSK
    Q(sqrt(2 Eb/N0)) = erfc(sqrt(Eb/N0)) / 2; non-coherent binary FSK exp(-Eb/(2 N0)) / 2."""
    if modulation == "bpsk":
        return 0.5 * math.erfc(math.sqrt(ebn0))
    return 0.5 * math.exp(-ebn0 / 2.0)


def ebn0(m: AcousticMedium, snr: float) -> float:
    """Linear Eb/N0 from the band SNR (dB): SNR * B / R."""
    return 10.0 ** (snr / 10.0) * m.bandwidth_khz * 1000.0 / m.bit_rate_bps


def frame_error_rate(
    m: AcousticMedium, range_m: float, size_bytes: int, noise_db: float | None = None
) -> float:
    """Probability that a frame of size_bytes (plus the modem's header) has a bit in error,
    with independent bit errors at the mean SNR: 1 - (1 - BER)^bits."""
    ber = bit_error_rate(m.modulation, ebn0(m, snr_db(m, range_m, noise_db)))
    bits = 8 * (size_bytes + m.header_bytes)
    if ber >= 0.5:
        return 1.0 - 0.5**bits
    return -math.expm1(bits * math.log1p(-ber))
