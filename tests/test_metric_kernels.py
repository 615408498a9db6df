"""The metrics' inner steps computed the cheap way equal their definitions (issue 13).

Each expected value is independent of the code under test: SciPy's peak finder and
prominences, an analytic baseline (a straight line under a sinusoid of exactly the period the
baseline averages over), and a Savitzky-Golay filter from SciPy at the window lengths the
amplitude uses (up to 129 samples).
"""
import numpy as np
import pytest
from scipy.signal import find_peaks as scipy_find_peaks
from scipy.signal import peak_prominences, savgol_filter as scipy_savgol

from hydroline.traces import filters, metrics
from hydroline.traces.peaks import local_maxima, peak_prominence


def test_peak_prominence_equals_scipy():
    rng = np.random.default_rng(5)
    for trial in range(40):
        x = rng.normal(size=int(rng.integers(5, 300)))
        if trial % 2:
            x = x.cumsum()
        if trial % 3 == 0:          # plateaus
            x = np.round(x * 2) / 2
        peaks = local_maxima(x)
        if peaks.size == 0:
            continue
        want = peak_prominences(x, peaks)[0]
        got = [peak_prominence(x, int(k)) for k in peaks]
        np.testing.assert_array_equal(got, want)


def _old_candidates(spectrum, freq, duration, dt, min_cycles=1.5, subharmonics=True,
                    every=False):
    """The spectral candidates of one spectrum as the module docstring defines them, by
    scipy.signal: the dominant peak (at least 10 times the median in range, every 8th bin)
    and its subharmonics; with ``every``, the dominant peak and then every other genuine
    peak at least 10 times the median, highest first."""
    in_range = (freq >= min_cycles / duration) & (freq <= 0.25 / dt)
    highest = float(np.max(spectrum[in_range]))
    peaks, _ = scipy_find_peaks(spectrum, prominence=0.02 * highest)
    peaks = peaks[in_range[peaks]]
    if peaks.size == 0:
        return []
    main = int(peaks[np.argmax(spectrum[peaks])])
    noise = 10 * np.median(spectrum[in_range][::8])
    if spectrum[main] < noise:
        return []
    out = [float(freq[main])]
    if every:
        rest = peaks[(peaks != main) & (spectrum[peaks] >= noise)]
        out += [float(freq[k]) for k in rest[np.argsort(-spectrum[rest], kind="stable")]]
    for k in range(2, 6 if subharmonics else 2):
        near = peaks[np.abs(freq[peaks] - freq[main] / k) <= 0.08 * freq[main] / k]
        if near.size and np.max(spectrum[near]) >= 0.1 * spectrum[main]:
            out.insert(0, float(freq[near[np.argmax(spectrum[near])]]))
    return out


@pytest.mark.parametrize("case", range(8))
def test_spectral_candidates_equal_scipy_find_peaks(case, monkeypatch):
    """The dominant peak and its subharmonics, found with a prominence only where it
    decides (the module's fast path), are those of scipy.signal.find_peaks over the whole
    spectrum restricted to the range: damped tones with strong harmonics or a weaker
    fundamental, drift and noise; then the dominant peak of the rate of change's spectrum
    (every genuine peak standing 10 times above its median, highest first, where the
    deviation's spectrum offers none), where it is another frequency."""
    rng = np.random.default_rng(100 + case)
    t = np.sort(rng.uniform(0.0, 0.12, 1400)) if case % 2 else np.linspace(0.0, 0.12, 1201)
    f = rng.uniform(25.0, 160.0)
    tau = np.clip(t - 0.01, 0.0, None)
    on = t >= 0.01
    p = 2e7 + on * (1e6 * np.exp(-rng.uniform(5, 60) * tau) * np.sin(2 * np.pi * f * tau)
                    + rng.uniform(0, 2.5e6) * np.exp(-30 * tau) * np.sin(4 * np.pi * f * tau)
                    - rng.uniform(0, 5e6) * tau)
    if case % 3 == 0:
        p = p + rng.normal(0.0, 1e4, t.size)
    seen = []
    rfft = metrics._rfft

    def recording(x, n):
        seen.append((x.copy(), n, rfft(x, n)))
        return seen[-1][2]

    monkeypatch.setattr(metrics, "_rfft", recording)
    ts, ps, _, p_final, _ = metrics._levels(t, p, 0.01)
    got = [f for f, _ in metrics._spectral_candidates(ts, ps, p_final, 1.5)]
    (x, n, deviation), (_, _, rate) = seen
    dt = (ts[-1] - ts[0]) / (x.size - 1)
    freq = np.fft.rfftfreq(n, dt)
    want = _old_candidates(np.abs(deviation), freq, ts[-1] - ts[0], dt)
    want += [f for f in _old_candidates(np.abs(rate), freq, ts[-1] - ts[0], dt,
                                        subharmonics=False, every=not want)
             if all(abs(f / g - 1) > 0.08 for g in want)]
    assert got == pytest.approx(want, rel=1e-12, abs=0.0)
    assert got, "a ringing trace has a dominant peak"


@pytest.mark.parametrize("dt", [1e-5, 2e-4, 1e-3])
def test_baseline_is_the_line_under_a_sinusoid(dt):
    """The one-period centred mean (running sums where a period holds more than 64 grid
    samples) and its continuation over the first and last half period (a line fitted
    together with a sinusoid of the period) give back the straight line under
    ``A sin(2 pi f t)`` exactly, but for the linear interpolation of the samples."""
    f = 40.0
    t = np.arange(0.0, 0.21 + dt / 2, dt)
    line = 2e7 + 3e6 * t
    p = line + 1e6 * np.sin(2 * np.pi * f * t + 0.3)
    grid, values, baseline = metrics.oscillation_baseline(t, p, 0.01, f)
    interpolation = 1e6 * (2 * np.pi * f * dt) ** 2 / 8      # bound on |values - p(grid)|
    assert np.max(np.abs(baseline - (2e7 + 3e6 * grid))) <= max(interpolation, 1e-3)
    half = int(round(1.0 / (f * (grid[1] - grid[0])))) // 2
    assert half > 0 and np.all(np.isfinite(baseline[:half]))


@pytest.mark.parametrize("window", [31, 65, 129])
def test_savgol_long_windows_equal_scipy(window):
    """The amplitude smooths over 1/8 period of up to 1024 samples: windows up to 129."""
    x = np.random.default_rng(window).normal(size=2000).cumsum() * 1e5 + 2e7
    np.testing.assert_allclose(filters.savgol_filter(x, window, 3),
                               scipy_savgol(x, window, 3, mode="interp"), rtol=1e-12)


def test_ring_time_is_the_softened_threshold_integrated():
    """``_time_above`` (the ring count's time above 1 %) against its definition integrated by
    brute force: ``clip(ln(v / level) + 1/2, 0, 1)`` on an envelope interpolated
    log-linearly, summed on 2000 sub-steps per segment; and against the closed form
    ``ln(a / level) / sigma`` of an exponential decay through the band (the hard threshold's
    time: the two halves of the ramp balance)."""
    rng = np.random.default_rng(23)
    level = 1.0
    for _ in range(20):
        times = np.cumsum(rng.uniform(0.1, 1.0, 30))
        values = np.exp(rng.normal(0.0, 0.8, 30))        # about the level, every way through
        sub = np.linspace(0.0, 1.0, 2001)
        total = 0.0
        for k in range(times.size - 1):
            logs = np.log(values[k]) + sub * (np.log(values[k + 1]) - np.log(values[k]))
            weight = np.clip(logs - np.log(level) + 0.5, 0.0, 1.0)
            total += (times[k + 1] - times[k]) * float(np.mean(
                0.5 * (weight[1:] + weight[:-1])))
        assert metrics._time_above(times, values, level) == pytest.approx(total, rel=1e-6)
    t = np.linspace(0.0, 1.0, 401)
    for a, sigma in ((100.0, 8.0), (3.0, 2.0), (1.7, 5.0)):    # starting above the band
        assert metrics._time_above(t, a * np.exp(-sigma * t), level) == pytest.approx(
            np.log(a / level) / sigma, rel=1e-12)
