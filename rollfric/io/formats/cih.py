"""Photron headers (``.cih`` text, ``.cihx`` XML) read into one dict of the ``.cih`` names.

pyMRAW's :func:`pyMRAW.get_cih` picks the format by a lower-case extension (a camera's
``BALL.CIHX`` is refused as an "unsupported configuration file"), keeps only a few ``.cihx``
entries (no start frame, no colour type) and passes the ``.cihx`` shutter speed on as if it
were seconds: it is the reciprocal, 1/s (``<shutterSpeed>50000`` is 20 us, as
``<shutterSpeedNsec>20000`` says). Here both formats give the ``.cih`` entry names, and
:func:`read_cih` adds ``shutter_s``, the exposure in seconds.
"""

from __future__ import annotations

from pathlib import Path

from rollfric.io.source import RecordingError

# .cihx element path -> the .cih text header's entry name
CIHX_NAMES = {
    "fileInfo/date": "Date",
    "fileInfo/time": "Time",
    "deviceInfo/deviceName": "Camera Type",
    "recordInfo/recordRate": "Record Rate(fps)",
    "recordInfo/shutterSpeed": "Shutter Speed(s)",
    "recordInfo/shutterSpeedNsec": "Shutter Type2(nsec)",
    "recordInfo/triggerTime": "Trigger Time",
    "frameInfo/totalFrame": "Total Frame",
    "frameInfo/recordedFrame": "Original Total Frame",
    "frameInfo/startFrame": "Start Frame",
    "imageDataInfo/resolution/width": "Image Width",
    "imageDataInfo/resolution/height": "Image Height",
    "imageDataInfo/colorInfo/type": "Color Type",
    "imageDataInfo/colorInfo/bit": "Color Bit",
    "imageDataInfo/effectiveBit/depth": "EffectiveBit Depth",
    "imageDataInfo/effectiveBit/side": "EffectiveBit Side",
    "imageFileInfo/fileFormat": "File Format",
    "basicInfo/comment": "Comment Text",
}


def _value(text: str):
    """A header value as int, float or the text (as pyMRAW converts them)."""
    text = text.strip()
    for kind in (int, float):
        try:
            return kind(text)
        except ValueError:
            pass
    return text


def _read_text(head: Path) -> dict:
    """The "key : value" lines of a ``.cih`` up to its first blank line."""
    cih = {}
    for line in head.read_bytes().decode("utf-8", errors="replace").splitlines():
        if not line.strip():
            break
        parts = line.split(" : ")
        if len(parts) == 2:
            cih[parts[0].strip()] = _value(parts[1])
    return cih


def _read_xml(head: Path) -> dict:
    """The ``<cih>`` element of a ``.cihx`` (after its binary preamble) by the ``.cih`` names."""
    import xml.etree.ElementTree as ET

    text = head.read_bytes().decode("utf-8", errors="ignore")
    a, b = text.find("<cih>"), text.rfind("</cih>")
    if a < 0 or b < a:
        raise ValueError("no <cih> element")
    root = ET.fromstring(text[a:b + len("</cih>")])
    cih = {}
    for where, name in CIHX_NAMES.items():
        node = root.find(where)
        if node is not None and node.text is not None and node.text.strip():
            cih[name] = _value(node.text)
    return cih


def shutter_seconds(cih: dict) -> float | None:
    """The exposure (s) a header states: ``Shutter Type2(nsec)`` (ns), else ``Shutter
    Speed(s)`` as "1/N" (a ``.cih``) or N (1/s, a ``.cihx``), else None.

    Parameters
    ----------
    cih : dict
        A header from :func:`read_cih` before ``shutter_s`` is added (``.cihx`` shutter speeds
        are written there as "1/N").

    Returns
    -------
    float or None
        Seconds; None when the header states none (or 0).
    """
    ns = cih.get("Shutter Type2(nsec)")
    if isinstance(ns, (int, float)) and ns > 0:
        return float(ns) * 1e-9
    s = cih.get("Shutter Speed(s)")
    if isinstance(s, str) and s.startswith("1/"):
        try:
            n = float(s[2:])
        except ValueError:
            return None
        return 1.0 / n if n > 0 else None
    if isinstance(s, (int, float)) and s > 0:
        return float(s)
    return None


def read_cih(head: str | Path) -> dict:
    """A Photron header by the ``.cih`` entry names, whatever the case of its extension.

    Parameters
    ----------
    head : str or pathlib.Path
        A ``.cih`` (text) or ``.cihx`` (XML) file.

    Returns
    -------
    dict
        Entry name -> int, float or str (``Total Frame``, ``Image Width``, ``Record
        Rate(fps)``, ``Start Frame``, ``Color Type``, ...), plus ``shutter_s`` (float seconds or
        None, :func:`shutter_seconds`).

    Raises
    ------
    RecordingError
        Not a readable header (the message names the file).
    """
    head = Path(head)
    xml = head.suffix.lower() == ".cihx"
    try:
        cih = _read_xml(head) if xml else _read_text(head)
    except OSError:
        raise
    except Exception as exc:  # ElementTree's ParseError, a missing <cih>, undecodable text
        raise RecordingError(f"{head}: not a readable Photron header ({type(exc).__name__}: "
                             f"{exc})") from None
    if xml and isinstance(cih.get("Shutter Speed(s)"), (int, float)):
        cih["Shutter Speed(s)"] = f"1/{cih['Shutter Speed(s)']}"  # the .cih's way: 1/s
    if not cih:
        raise RecordingError(f"{head}: not a readable Photron header (no 'key : value' entries)")
    cih["shutter_s"] = shutter_seconds(cih)
    return cih
