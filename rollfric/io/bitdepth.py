"""The camera's effective bit depth: the full scale every threshold, floor and saturation test
is taken against.

A 12-bit camera's frames come in 16-bit words (values 0..4095): taking the word's 65535 as
their full scale puts every threshold that is a fraction of full scale 16x too high (a ball of
367 DN contrast is then "no ball-like change"), and a clipped edge at 4095 is never seen as
saturated. The depth comes, in this order, from the file (a reader's ``bit_depth_stated``: the
cine's real bit depth, the Photron header's effective bit depth, a TIFF's ``MaxSampleValue`` or
``BitsPerSample``, 8 for 8-bit images and video), from the setup key ``camera.bit_depth``, or
from the data: the smallest depth that holds the largest value of a few sampled frames (with a
warning).
"""

from __future__ import annotations

import logging
import math

import numpy as np

from rollfric.errors import InputError

logger = logging.getLogger(__name__)

MIN_BITS, MAX_BITS = 1, 16
SAMPLED_FRAMES = 5  # frames whose largest value checks or guesses the depth


def full_scale(bits: int) -> float:
    """The largest value of a ``bits``-bit camera: 2**bits - 1.

    Parameters
    ----------
    bits : int
        The camera's effective bit depth (1..16).

    Returns
    -------
    float
        2**bits - 1 (DN).
    """
    return float(2 ** int(bits) - 1)


def dtype_bits(dtype) -> int:
    """The bits of an integer pixel type (8 for uint8, 16 for uint16).

    Parameters
    ----------
    dtype : numpy.dtype or type

    Returns
    -------
    int
    """
    return 8 * np.dtype(dtype).itemsize


def bits_for(value: float) -> int:
    """The smallest bit depth whose full scale holds ``value`` (at least 1).

    Parameters
    ----------
    value : float
        A pixel value (DN, >= 0).

    Returns
    -------
    int
    """
    return max(MIN_BITS, int(math.ceil(math.log2(float(value) + 1.0))) if value > 0 else 1)


def sampled_max(source, k: int = SAMPLED_FRAMES) -> tuple[int, int]:
    """The largest value of up to ``k`` frames spread evenly over the recording.

    Parameters
    ----------
    source : FrameSource
    k : int, optional
        Frames read.

    Returns
    -------
    vmax : int
        The largest pixel value (DN).
    n : int
        The frames read.
    """
    n = len(source)
    idx = np.unique(np.linspace(0, n - 1, min(n, max(1, int(k)))).round().astype(int))
    return max(int(np.max(source[int(i)])) for i in idx), len(idx)


def check_bits(value, where: str) -> int:
    """A bit depth as a setup or a file states it, checked: an integer 1..16.

    Parameters
    ----------
    value : object
        The value given.
    where : str
        Its name in the message.

    Returns
    -------
    int

    Raises
    ------
    InputError
        Not an integer of 1..16.
    """
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) \
            or not MIN_BITS <= int(value) <= MAX_BITS:
        raise InputError(f"{where} must be a whole number of bits, {MIN_BITS}..{MAX_BITS}, got "
                         f"{value!r}")
    return int(value)


def resolve_bit_depth(source, setup_bits: int | None = None, *,
                      where: str = "camera.bit_depth") -> tuple[int, str, list[str]]:
    """The recording's effective bit depth: the file's, else the setup's, else the data's.

    The setup's value must agree with the file's where the file states one, and no sampled
    frame may exceed the full scale of the depth the setup states. A file's statement that its
    own sampled frames exceed is not used (a note says so). A depth from the data is
    the smallest that holds the largest value of :data:`SAMPLED_FRAMES` sampled frames (a dim
    recording then gets a low depth: its thresholds are then lower, as they should be for its
    range), with a note saying so.

    Parameters
    ----------
    source : FrameSource
        The recording; a reader's ``bit_depth_stated`` (int or None) is what its file says.
    setup_bits : int or None, optional
        The setup's ``camera.bit_depth``.
    where : str, optional
        The setup key's name in the messages.

    Returns
    -------
    bits : int
        The depth (1..16, at most the frames' word size).
    how : str
        Where it came from ("file", "setup" or "data").
    notes : list of str
        Warnings (a depth taken from the data).

    Raises
    ------
    InputError
        The setup's value contradicts the file's, exceeds the frames' word, or the sampled
        frames exceed its full scale.
    """
    word = dtype_bits(source.dtype)
    stated = getattr(source, "bit_depth_stated", None)
    name = getattr(source, "name", "the recording")
    wrong = []  # the file's statement, when its own frames exceed it
    if stated is not None and int(stated) < word:
        vmax, k = sampled_max(source)
        if vmax > full_scale(int(stated)):
            wrong = [f"{name} says the camera's bit depth is {int(stated)} (full scale "
                     f"{full_scale(int(stated)):.0f} DN), but {k} sampled frames reach {vmax} DN: "
                     "not used"]
            stated = None
    if setup_bits is not None:
        setup_bits = check_bits(setup_bits, where)
        if setup_bits > word:
            raise InputError(f"{where} = {setup_bits} but the frames of {name} are "
                             f"{word}-bit words: a camera's depth cannot exceed them")
        if stated is not None and int(stated) != setup_bits:
            raise InputError(f"{where} = {setup_bits} contradicts {name}, whose file says the "
                             f"camera's bit depth is {int(stated)}: remove the key or correct it")
        if setup_bits < word:
            vmax, k = sampled_max(source)
            if vmax > full_scale(setup_bits):
                raise InputError(f"{where} = {setup_bits} (full scale "
                                 f"{full_scale(setup_bits):.0f} DN) contradicts the data of "
                                 f"{name}: {k} sampled frames reach {vmax} DN")
        return setup_bits, "setup", wrong
    if stated is not None:
        return int(stated), "file", []
    if word == 8:
        return 8, "file", wrong
    vmax, k = sampled_max(source)
    bits = min(word, bits_for(vmax))
    note = (f"the camera's bit depth is neither in {name} nor in the setup: taken as {bits} "
            f"from the data (the largest value of {k} sampled frames is {vmax} DN; full scale "
            f"{full_scale(bits):.0f} DN); give {where} in the setup if the camera's is another")
    return bits, "data", wrong + [note]
