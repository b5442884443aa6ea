"""Reading a text file (YAML) so that every failure is one ``ValueError`` naming the file and what is wrong."""

from __future__ import annotations

from pathlib import Path

__all__ = ["read_text_file"]


def read_text_file(path, what: str) -> str:
    """The UTF-8 text of ``path`` (a leading byte-order mark dropped).

    Parameters
    ----------
    path : path-like
    what : str
        What the file should be, for the message, e.g. ``"a capture.yaml (dptpu-capture/1)"``.

    Raises
    ------
    FileNotFoundError
        No such file.
    ValueError
        A folder, an unreadable file (permissions, I/O error) or bytes that are not UTF-8, e.g.
        ``capture.yaml: not UTF-8 text (byte 0xef at offset 0); expected a capture.yaml (dptpu-capture/1)``.
    """
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"{path}: no such file; expected {what}")
    if path.is_dir():
        raise ValueError(f"{path}: is a folder; expected {what}")
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise ValueError(f"{path}: cannot read ({exc.strerror or exc}); expected {what}") from None
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise ValueError(f"{path}: not UTF-8 text (byte 0x{data[exc.start]:02x} at offset {exc.start}); "
                         f"expected {what}") from None
