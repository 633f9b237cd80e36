"""The sub-pixel locator's kernels against plain NumPy: the same numbers, not close ones."""

import numpy as np
import pytest

from rollfric.locate.kernels.rim import _rim_median_plain
from rollfric.locate.kernels.rim import rim_median as _rim_median


def _rim_median_numpy(values, ok, min_count):
    """The rim median as its docstring says: np.median of each wrapped window of ok rays."""
    n = len(values)
    half = max(2, n // 16)
    out = np.full(n, np.nan)
    for i in range(n):
        q = [(i + j) % n for j in range(-half, half + 1)]
        w = [values[k] for k in q if ok[k]]
        if len(w) >= min_count and len(w) > 0:
            out[i] = np.median(w)
    return out


@pytest.mark.parametrize("seed", range(6))
def test_rim_median_is_the_windows_median(seed):
    # the sliding sorted window gives each window's np.median exactly: ties, zeros, windows
    # longer than the ring (few rays), rays left out, odd and even counts (a median of 0.0 may
    # come out as -0.0 or the reverse where both are in the window: equal as numbers, and the
    # kernels only compare and subtract it)
    rng = np.random.default_rng(seed)
    for n in (1, 2, 3, 5, 17, 48, 93, 232, 360):
        for frac in (0.0, 0.3, 0.8, 1.0):
            v = rng.normal(size=n) * 10.0 ** rng.integers(-3, 4)
            if seed % 2:
                v = np.round(v, 1)  # many equal values
            v[rng.random(n) < 0.1] = 0.0
            ok = rng.random(n) < frac
            for min_count in (0, 1, 3):
                got = _rim_median(v, ok, min_count)
                want = _rim_median_numpy(v, ok, min_count)
                assert np.array_equal(got, want, equal_nan=True), (n, frac, min_count)
                nz = want != 0.0
                assert got[nz].tobytes() == want[nz].tobytes()


def test_rim_median_with_nan_values_window_by_window():
    # a NaN among the rays (none of the locator's calls pass one) takes the window-by-window
    # path: numba's np.median of each window, as before the sliding window
    v = np.linspace(0.0, 1.0, 64)
    v[10] = np.nan
    ok = np.ones(64, bool)
    got = _rim_median(v, ok, 1)
    assert np.array_equal(got, _rim_median_plain(v, ok, 1, 4), equal_nan=True)
    assert np.isfinite(got[40])
    assert np.array_equal(got[20:50], _rim_median_numpy(v, ok, 1)[20:50])


def test_ray_index_is_arctan2s_ray():
    # the pixel fit's ray of a pixel from the polynomial angle (off a ray's boundary) or
    # arctan2 (near it): arctan2's index everywhere - random points, the pixel grid about a
    # centre off the grid, points on and next to the rays' boundaries, the axes and -0.0
    from rollfric.jit import njit
    from rollfric.locate.kernels.pixelfit import _ray_index

    @njit
    def both(xs, ys, n):
        out = np.empty((2, xs.size), np.int64)
        for i in range(xs.size):
            phi = np.arctan2(ys[i], xs[i])
            if phi < 0:
                phi += 2 * np.pi
            out[0, i] = int(phi / (2 * np.pi / n)) % n
            out[1, i] = _ray_index(xs[i], ys[i], n)
        return out

    rng = np.random.default_rng(0)
    gx, gy = np.meshgrid(np.arange(-45, 46) - 0.37, np.arange(-45, 46) + 0.11)
    for n in (7, 8, 94, 234, 360):
        ang = np.arange(4 * n) * (np.pi / (2 * n))
        ang = np.concatenate([ang, np.nextafter(ang, 10.0), np.nextafter(ang, -10.0)])
        xs = np.concatenate([rng.uniform(-60, 60, 200_000), gx.ravel(), 38.0 * np.cos(ang),
                             [1.0, -1.0, 0.0, 0.0, -1.0, 1.0, -0.0, -3.0, 1e-300]])
        ys = np.concatenate([rng.uniform(-60, 60, 200_000), gy.ravel(), 38.0 * np.sin(ang),
                             [0.0, 0.0, 1.0, -1.0, -0.0, -0.0, 5.0, -0.0, -1e-300]])
        want, got = both(xs, ys, n)
        np.testing.assert_array_equal(got, want)


def test_ring_sums_are_the_whole_crops_scan():
    # the ring's sums from each row's chord (and hypot only near the ring's edges) are those
    # of a scan of every pixel with hypot, to the bit: centres on and off the pixel grid,
    # integer radii whose edges pass through pixel centres (3-4-5), empty and inverted rings,
    # crops at the frame's corner
    import math

    from rollfric.jit import njit
    from rollfric.locate.kernels.crops import ring_sums as _ring_sums

    @njit
    def scan(fr, bg, x0, y0, cx, cy, r_in, r_out):
        sf = 0.0
        sb = 0.0
        cnt = 0
        for iy in range(fr.shape[0]):
            for ix in range(fr.shape[1]):
                d = math.hypot((ix + x0) - cx, (iy + y0) - cy)
                if d >= r_in and d <= r_out:
                    sf += np.float64(fr[iy, ix])
                    sb += np.float64(bg[iy, ix])
                    cnt += 1
        return sf, sb, cnt

    rng = np.random.default_rng(2)
    fr = rng.integers(0, 4096, (160, 170)).astype(np.uint16)
    bg = rng.integers(0, 4096, (160, 170)).astype(np.uint16)
    cases = [(80.0, 70.0, 5.0, 10.0), (80.0, 70.0, 0.0, 5.0), (80.5, 70.5, 2.5, 7.5),
             (0.0, 0.0, 3.0, 40.0), (80.0, 70.0, 10.0, 5.0), (80.0, 70.0, -1.0, 0.0)]
    for _ in range(3000):
        r = rng.uniform(0.3, 60.0)
        cases.append((rng.uniform(-10, 180), rng.uniform(-10, 170), r + 2, r + 6))
        cases.append((float(rng.integers(0, 170)), float(rng.integers(0, 160)),
                      float(rng.integers(0, 20)), float(rng.integers(0, 40))))
    for cx, cy, r_in, r_out in cases:
        x0, y0 = int(rng.integers(0, 60)), int(rng.integers(0, 60))
        f = fr[y0:y0 + int(rng.integers(1, 100)), x0:x0 + int(rng.integers(1, 110))]
        b = bg[y0:y0 + f.shape[0], x0:x0 + f.shape[1]]
        assert _ring_sums(f, b, x0, y0, cx, cy, r_in, r_out) == \
            scan(f, b, x0, y0, cx, cy, r_in, r_out), (cx, cy, r_in, r_out)


def test_same_values_is_array_equal():
    from rollfric.locate.kernels.crops import same_values as _same_values

    rng = np.random.default_rng(4)
    a = rng.integers(0, 4096, (30, 41)).astype(np.uint16)
    assert _same_values(a, a.copy()) and _same_values(a[3:9, 2:40], a.copy()[3:9, 2:40])
    for iy, ix in [(0, 0), (29, 40), (12, 7)]:
        b = a.copy()
        b[iy, ix] ^= 1
        assert not _same_values(a, b) and not np.array_equal(a, b)
    assert _same_values(a[:0], a[:0])
