"""Camera sensor: photo-electrons in, digital numbers out (docs/imaging.md §4).

For each pixel, independently, with μ = signal + background expected electrons::

    k  ~ Poisson(μ)                         shot noise (photo + dark/background e⁻)
    k  ← min(k, ⌊full_well⌋)                saturation of the well
    v  = gain · (k + r) + offset,  r ~ N(0, read_noise²)      read noise, e⁻ rms
    DN = clip(round(v), 0, 2^bit_depth − 1)                     ADC (round half to even)

The input is expected photo-electrons: quantum efficiency is folded into it. The
noise-free mode replaces k by min(μ, ⌊full_well⌋) and r by 0.

How it stays exact and fast: every pixel without signal has the *same* DN
distribution, that of a pure background pixel (Poisson(background) convolved with the
read noise, scaled, rounded and clipped). It is tabulated once per sensor to double
precision (tails below ~10⁻²⁰ dropped) and sampled by inversion from 16 random bits per
pixel: a look-up table of the 2¹⁶ equal cells of [0, 1) gives the DN of every cell that
lies within one DN's share of the CDF; a pixel whose cell straddles a boundary (about
one in a thousand) draws a double-precision uniform within its cell and searches the
CDF. A pixel with a weak signal μ_s <= 25 e⁻ draws one uniform u and inverts the Poisson
CDF of its signal electrons k_s; when k_s = 0 (u < e^{−μ_s}, three pixels in four on a
particle image, most of them in the tails of the spots) it reads as a background pixel,
sampled from the same table with the uniform u / e^{−μ_s}; otherwise its count is k_s
plus a Poisson(background) draw. Brighter pixels follow the three steps above with
NumPy's Poisson and normal generators. Every path draws from the same exact
distribution (Poisson(μ_s) + Poisson(background) is Poisson(μ)); nothing is
approximated by a Gaussian. When the background is so large that its table would be
expensive (> 4·10⁶ entries, e.g. 10⁴ e⁻ at a gain of 4 DN/e⁻), every pixel takes the
per-pixel path, which is exact but several times slower.
"""

import logging
from dataclasses import dataclass
from functools import lru_cache
from math import ceil, floor, sqrt
from typing import NamedTuple

import numpy as np
from numba import njit
from scipy import special

from simulator.render._checks import finite_float, first_bad, positive_float

logger = logging.getLogger(__name__)

#: Poisson and Gaussian tails kept when tabulating the background DN distribution.
_TAIL_SIGMAS = 12.0
#: Beyond this many (k, DN) table entries the per-pixel path is used for every pixel.
_MAX_TABLE_WORK = 4_000_000
#: Random bits per zero-signal pixel: the look-up tables have 2^16 cells.
_CELL_BITS = 16
#: Pixels per chunk of the table path (128 KiB of random bits).
_CHUNK = 1 << 18
#: Signals up to this many expected e⁻ invert the Poisson CDF in the compiled loop (at
#: most ~μ_s + 1 steps); brighter pixels use NumPy's Poisson generator.
_INVERSION_MAX = 25.0
_FLOAT_MAX = float(np.finfo(np.float64).max)
#: The largest double below 1: (cell + u) / 2^16 may round up to 1, outside the CDF.
_BELOW_ONE = 1.0 - 2.0**-53


class BackgroundTable(NamedTuple):
    """Inverse-CDF table of the DN of a pixel without signal.

    Attributes
    ----------
    cdf : ndarray, shape (n,)
        cdf[i] = P(DN <= dn_lo + i); cdf[-1] = 1.
    cells : ndarray of int32, shape (2^16,)
        For the uniforms u in cell j, [j, j + 1) / 2^16: the index i of their DN
        (the first i with cdf[i] > u) when it is the same for the whole cell, else
        −1 − (that index at the cell's lower end).
    dn : ndarray of uint16, shape (2^16,)
        The DN of each cell, dn_lo + cells[j], or ``straddles`` where the cell straddles
        a CDF boundary.
    dn_lo : int
        Smallest DN tabulated.
    straddles : int
        A DN outside the table, marking the cells that straddle a boundary.
    """

    cdf: np.ndarray
    cells: np.ndarray
    dn: np.ndarray
    dn_lo: int
    straddles: int


@dataclass(frozen=True)
class Sensor:
    """Linear camera sensor with shot noise, read noise, full well and an ADC.

    Parameters
    ----------
    gain : float
        Conversion gain, DN per e⁻, > 0.
    read_noise : float
        Read noise σ_read, e⁻ rms, >= 0.
    offset : float
        Black level added before rounding, DN (keeps read noise from clipping at 0).
    full_well : float
        Well capacity, e⁻, >= 1; electron counts saturate at ⌊full_well⌋.
    bit_depth : int
        ADC bits B, 8 to 16; DN are clipped to [0, 2^B − 1].
    background : float
        Dark current plus stray light, expected e⁻ per pixel per exposure, >= 0.
        Shot noise applies to it as to the signal.

    Examples
    --------
    A spot of 1000 e⁻ recorded at 0.4 DN/e⁻ above a black level of 10 DN, without
    noise and with it:

    >>> import simulator
    >>> spot = simulator.render_particles([[2.0, 2.0]], 0.8, 1000.0, shape=(5, 5)).image  # e⁻
    >>> sensor = simulator.Sensor(gain=0.4, read_noise=8.0, offset=10.0, bit_depth=12)
    >>> sensor.record(spot, noise=False)[2]  # the middle row, DN
    array([16, 54, 98, 54, 16], dtype=uint16)
    >>> frame = sensor.record(spot, rng=0)  # shot and read noise
    >>> frame.shape, frame.dtype, sensor.max_dn
    ((5, 5), dtype('uint16'), 4095)
    """

    gain: float = 0.4
    read_noise: float = 8.0
    offset: float = 10.0
    full_well: float = 10_000.0
    bit_depth: int = 12
    background: float = 0.0

    def __post_init__(self) -> None:
        positive_float("gain", self.gain)
        positive_float("read_noise", self.read_noise, allow_zero=True)
        finite_float("offset", self.offset)
        if positive_float("full_well", self.full_well) < 1:
            raise ValueError(f"full_well must be >= 1 e⁻, got {self.full_well!r}")
        positive_float("background", self.background, allow_zero=True)
        b = self.bit_depth
        if not isinstance(b, int | np.integer) or isinstance(b, bool) or not 8 <= b <= 16:
            raise ValueError(f"bit_depth must be an integer from 8 to 16, got {b!r}")

    @property
    def well(self) -> int:
        """Saturation count ⌊full_well⌋, e⁻."""
        return floor(self.full_well)

    @property
    def max_dn(self) -> int:
        """Largest digital number, 2^B − 1."""
        return (1 << int(self.bit_depth)) - 1

    def record(
        self,
        electrons: object,
        rng: np.random.Generator | int | None = None,
        *,
        noise: bool = True,
    ) -> np.ndarray:
        """Digitise an image of expected photo-electrons.

        Parameters
        ----------
        electrons : array_like, shape (H, W)
            Expected signal photo-electrons per pixel, finite and >= 0 (the sensor's
            ``background`` is added here).
        rng : numpy.random.Generator, int or None
            Source of randomness; ignored when ``noise`` is False.
        noise : bool
            False: noise-free mode, DN = clip(round(gain · min(μ, well) + offset)), with
            μ = electrons + background and well = ⌊full_well⌋.

        Returns
        -------
        ndarray, shape (H, W), uint16
            Digital numbers in [0, 2^B − 1].
        """
        signal = _signal_image(electrons, check_values=not noise)
        if not noise:
            out = np.empty(signal.shape, dtype=np.uint16)
            _digitise_expected(
                signal.reshape(-1),
                float(self.background),
                float(self.well),
                float(self.gain),
                float(self.offset),
                self.max_dn,
                out.reshape(-1),
            )
            return out
        gen = np.random.default_rng(rng)
        flat = signal.reshape(-1)
        out = np.empty(flat.size, dtype=np.uint16)
        table = _background_table(
            float(self.background),
            float(self.gain),
            float(self.offset),
            float(self.read_noise),
            float(self.well),
            int(self.bit_depth),
        )
        if table is None:
            _check_values(signal)
            lit = np.arange(flat.size)
            self._record_shot(out, lit, gen.poisson(self._capped(flat + self.background)), gen)
        else:
            lit = _record_background(signal, gen, table, out)
            self._record_signal(flat, lit, gen, table, out)
        logger.debug(
            "recorded %d px, %d with signal (%s path for the rest)",
            flat.size,
            lit.size,
            "table" if table is not None else "per-pixel",
        )
        return out.reshape(signal.shape)

    def _record_signal(
        self,
        flat: np.ndarray,
        lit: np.ndarray,
        gen: np.random.Generator,
        table: BackgroundTable,
        out: np.ndarray,
    ) -> None:
        """Record the pixels ``lit`` (signal > 0) into ``out``: weak signals by inversion
        (one uniform per lit pixel), the rest with NumPy's Poisson generator."""
        signal = flat[lit]
        n, listed, shot = _invert_weak_signals(
            signal, np.exp(-signal), lit, gen.random(lit.size), table, out
        )
        listed, shot = listed[:n], shot[:n]
        bright = shot < 0
        electrons = shot.copy()
        electrons[bright] = gen.poisson(self._capped(flat[listed[bright]] + self.background))
        if self.background > 0:
            electrons[~bright] += gen.poisson(self.background, n - np.count_nonzero(bright))
        self._record_shot(out, listed, electrons, gen)

    def _capped(self, mean: np.ndarray) -> np.ndarray:
        return np.minimum(mean, _poisson_cap(self.well))

    def _record_shot(
        self, out: np.ndarray, idx: np.ndarray, electrons: np.ndarray, gen: np.random.Generator
    ) -> None:
        """out[idx] = DN of ``electrons`` (saturated at the well) plus read noise."""
        counts = np.minimum(electrons, self.well).astype(np.float64)
        if self.read_noise > 0:
            counts += self.read_noise * gen.standard_normal(idx.size)
        out[idx] = self._digitise(counts)

    def _digitise(self, counts: np.ndarray) -> np.ndarray:
        dn = np.rint(self.gain * counts + self.offset)
        return np.clip(dn, 0, self.max_dn).astype(np.uint16)


def _signal_image(electrons: object, *, check_values: bool) -> np.ndarray:
    arr = np.asarray(electrons)
    if arr.ndim != 2:
        raise ValueError(f"electrons must be a 2-D image (H, W), got shape {arr.shape}")
    if arr.dtype == bool or not (
        np.issubdtype(arr.dtype, np.floating) or np.issubdtype(arr.dtype, np.integer)
    ):
        raise ValueError(f"electrons must be real numbers, got dtype {arr.dtype}")
    arr = np.ascontiguousarray(arr, dtype=np.float64)
    if check_values:
        _check_values(arr)
    return arr


def _check_values(arr: np.ndarray) -> None:
    """Raise ValueError naming the first pixel that is negative, NaN or infinite."""
    bad = ~(np.isfinite(arr) & (arr >= 0))
    if bad.any():
        raise first_bad("electrons", arr, bad, "finite and >= 0")


def _record_background(
    signal: np.ndarray, gen: np.random.Generator, table: BackgroundTable, out: np.ndarray
) -> np.ndarray:
    """Fill ``out`` at zero-signal pixels from the table; return the other pixels' indices.

    Works in chunks so that the random bits stay in cache and no frame-sized scratch
    array is faulted in on every call. Per chunk: 16 random bits per pixel (four per
    64-bit word of the generator) give every pixel its cell's DN; then one uniform per
    zero-signal pixel whose cell straddles a CDF boundary.
    """
    flat = signal.reshape(-1)
    chunk = min(_CHUNK, flat.size)
    lit = np.empty(chunk, dtype=np.int64)
    straddling = np.empty(chunk, dtype=np.int64)
    parts = []
    for start in range(0, flat.size, chunk):
        stop = min(start + chunk, flat.size)
        bits = gen.bit_generator.random_raw(-(-(stop - start) // 4))
        _look_up_cells(bits, table.dn, out[start:stop])
        n_lit, n_straddling = _split_pixels(
            flat[start:stop], out[start:stop], table.straddles, lit, straddling
        )
        if n_lit < 0:
            _check_values(signal)
        pixels = straddling[:n_straddling]
        cell = (bits[pixels >> 2] >> (16 * (pixels & 3)).astype(np.uint64)) & np.uint64(0xFFFF)
        uniform = np.minimum((cell + gen.random(n_straddling)) / (1 << _CELL_BITS), _BELOW_ONE)
        _fill_from_uniforms(pixels, uniform, table.cells, table.cdf, table.dn_lo, out[start:stop])
        if n_lit:
            parts.append(lit[:n_lit] + start)
    return np.concatenate(parts) if parts else np.empty(0, dtype=np.int64)


def _poisson_cap(full_well: float) -> float:
    """A Poisson mean λ with P(Poisson(λ) < full_well) < 1e-300 (Chernoff bound).

    Capping the mean there changes no recorded count (they saturate at the full well
    either way) and keeps absurd signals from overflowing NumPy's generator.
    """
    return 2.0 * full_well + 40.0 * sqrt(full_well) + 1000.0


def _poisson_pmf(k: np.ndarray, mean: float) -> np.ndarray:
    if mean == 0:
        return (k == 0).astype(np.float64)
    return np.exp(k * np.log(mean) - mean - special.gammaln(k + 1.0))


@lru_cache(maxsize=32)
def _background_table(
    background: float,
    gain: float,
    offset: float,
    read_noise: float,
    full_well: float,
    bit_depth: int,
) -> BackgroundTable | None:
    """Inverse-CDF table of the DN of a pixel without signal, or None if too large."""
    max_dn = (1 << bit_depth) - 1
    spread = _TAIL_SIGMAS * sqrt(background)
    k_lo = max(0, floor(background - spread - _TAIL_SIGMAS))
    k_hi = min(ceil(background + spread + 3 * _TAIL_SIGMAS), floor(full_well))
    if k_lo > k_hi:  # the whole Poisson mass lies at or above the full well
        k_lo = k_hi
    k = np.arange(k_lo, k_hi + 1, dtype=np.float64)
    pk = _poisson_pmf(k, background)
    # Saturation: everything at or above the full well reads as the full well.
    above = special.pdtrc(k_hi, background) if background > 0 else 0.0
    if floor(full_well) <= k_hi:
        pk[-1] += above
    value = gain * k + offset
    read = gain * read_noise
    if read == 0:
        dn = np.clip(np.rint(value), 0, max_dn).astype(np.int64)
        dn_lo, dn_hi = int(dn.min()), int(dn.max())
        if (dn_hi - dn_lo + 1) > _MAX_TABLE_WORK:
            return None
        pmf = np.bincount(dn - dn_lo, weights=pk, minlength=dn_hi - dn_lo + 1)
    else:
        dn_lo = int(np.clip(floor(value[0] - _TAIL_SIGMAS * read), 0, max_dn))
        dn_hi = int(np.clip(ceil(value[-1] + _TAIL_SIGMAS * read), 0, max_dn))
        d = np.arange(dn_lo, dn_hi + 1, dtype=np.float64)
        if k.size * d.size > _MAX_TABLE_WORK:
            return None
        with np.errstate(over="ignore"):  # a read noise ~1e-308 e⁻: ±inf, still exact
            lo = (d[None, :] - 0.5 - value[:, None]) / read
            hi = (d[None, :] + 0.5 - value[:, None]) / read
        lo[:, 0] = np.where(dn_lo == 0, -np.inf, lo[:, 0])
        hi[:, -1] = np.where(dn_hi == max_dn, np.inf, hi[:, -1])
        # P(lo < Z < hi) for Z ~ N(0, 1), in the form exact in both tails.
        upper = lo >= 0
        p = np.where(
            upper,
            special.ndtr(-lo) - special.ndtr(-hi),
            special.ndtr(hi) - special.ndtr(lo),
        )
        pmf = pk @ p
    cdf = np.cumsum(pmf)
    cdf /= cdf[-1]
    cdf[-1] = 1.0
    lower = np.arange(1 << _CELL_BITS) / (1 << _CELL_BITS)
    first = np.searchsorted(cdf, lower, side="right")  # the first i with cdf[i] > u
    whole = cdf[first] >= lower + 1.0 / (1 << _CELL_BITS)
    cells = np.where(whole, first, -1 - first).astype(np.int32)
    dn_hi = dn_lo + cdf.size - 1
    if dn_hi < 0xFFFF:
        straddles = 0xFFFF
    elif dn_lo > 0:
        straddles = 0
    else:  # every 16-bit DN is possible: no marker left (and a huge table anyway)
        return None
    dn = np.where(whole, dn_lo + first, straddles).astype(np.uint16)
    for arr in (cdf, cells, dn):
        arr.setflags(write=False)
    return BackgroundTable(cdf, cells, dn, dn_lo, straddles)


@njit(cache=True, inline="always")
def _invert(cells, cdf, u):  # pragma: no cover (compiled)
    """The index i of the DN of uniform u in [0, 1): the first i with cdf[i] > u."""
    c = cells[min(int(u * cells.size), cells.size - 1)]
    i = c if c >= 0 else -1 - c
    while cdf[i] <= u:
        i += 1
    return i


@njit(cache=True)
def _look_up_cells(bits, dn, out):  # pragma: no cover (compiled)
    """out[p] = dn[cell of pixel p]: bits 16·(p mod 4) … 16·(p mod 4) + 15 of word p // 4."""
    n = out.size
    for w in range(n >> 2):
        word = bits[w]
        out[4 * w] = dn[word & np.uint64(0xFFFF)]
        out[4 * w + 1] = dn[(word >> np.uint64(16)) & np.uint64(0xFFFF)]
        out[4 * w + 2] = dn[(word >> np.uint64(32)) & np.uint64(0xFFFF)]
        out[4 * w + 3] = dn[word >> np.uint64(48)]
    for p in range(n & ~3, n):
        out[p] = dn[(bits[p >> 2] >> np.uint64(16 * (p & 3))) & np.uint64(0xFFFF)]


@njit(cache=True)
def _split_pixels(signal, out, straddles, lit, straddling):  # pragma: no cover (compiled)
    """List the pixels with signal in ``lit``, the zero-signal pixels whose cell
    straddles a boundary (``out`` = ``straddles``) in ``straddling``.

    Returns (len(lit), len(straddling)), or (−1, 0) if a pixel is negative, NaN or
    infinite.
    """
    n_lit = 0
    n_straddling = 0
    for p in range(signal.size):
        s = signal[p]
        if s != 0.0 or out[p] == straddles:
            if s == 0.0:
                straddling[n_straddling] = p
                n_straddling += 1
            elif s > 0.0 and s <= _FLOAT_MAX:
                lit[n_lit] = p
                n_lit += 1
            else:
                return -1, 0
    return n_lit, n_straddling


@njit(cache=True)
def _fill_from_uniforms(pixels, u, cells, cdf, dn_lo, out):  # pragma: no cover
    """out[pixels[j]] = the background DN of uniform u[j]."""
    for j in range(pixels.size):
        out[pixels[j]] = dn_lo + _invert(cells, cdf, u[j])


@njit(cache=True)
def _invert_weak_signals(signal, p_zero, lit, u, table, out):  # pragma: no cover
    """Signal electrons k_s ~ Poisson(μ_s) of the weak lit pixels, by inversion with u.

    For lit pixel j (flat index lit[j], μ_s = signal[j], P(k_s = 0) = p_zero[j] =
    e^{−μ_s}, given so that NumPy computes it in SIMD): if μ_s > _INVERSION_MAX it
    is listed with k = −1 (for the Poisson generator); else k_s is the inverse Poisson
    CDF of u[j]. Where k_s = 0 the pixel reads as a background pixel: its DN, drawn from
    the table with the uniform u[j] / e^{−μ_s}, goes to ``out``; otherwise it is listed
    with k = k_s. Tails beyond μ_s + 12√μ_s + 12 e⁻, less likely than the rounding of the
    cumulative sum (~10⁻¹⁵), go to that count.

    Returns (n, listed, k): the first n entries of listed and k are the pixels left.
    """
    cdf, cells, _, dn_lo, _ = table
    listed = np.empty(lit.size, np.int64)
    shot = np.empty(lit.size, np.int64)
    n = 0
    for j in range(lit.size):
        p = lit[j]
        mu = signal[j]
        if mu > _INVERSION_MAX:
            listed[n] = p
            shot[n] = -1
            n += 1
            continue
        pk = p_zero[j]
        if u[j] < pk:
            out[p] = dn_lo + _invert(cells, cdf, min(u[j] / pk, _BELOW_ONE))
            continue
        top = int(mu + 12.0 * sqrt(mu) + 12.0)
        k = 0
        total = pk
        while u[j] >= total and k < top:
            k += 1
            pk *= mu / k
            total += pk
        listed[n] = p
        shot[n] = k
        n += 1
    return n, listed, shot


@njit(cache=True)
def _digitise_expected(signal, background, well, gain, offset, max_dn, out):  # pragma: no cover
    """Noise-free DN = clip(rint(gain · min(signal + background, well) + offset))."""
    for p in range(signal.size):
        v = np.rint(gain * min(signal[p] + background, well) + offset)
        out[p] = min(max(v, 0.0), max_dn)
