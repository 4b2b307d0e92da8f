"""Bytes from a file someone else wrote, as text: one-line errors that name the line of the bad byte.

The web importer, the analysis readers and the runner's resume all read files they did not write
(a participant's download, another lab's table, a session file edited by hand); each refuses a NUL
byte (a binary file, UTF-16 text) and bytes that are not UTF-8 the same way, through :func:`decoded`.
"""

from __future__ import annotations

from appeal.errors import AppealInputError

__all__ = ["line_of", "decoded"]


def line_of(data: bytes, offset: int) -> int:
    """The 1-based line of ``data`` that byte ``offset`` is on."""
    return data.count(b"\n", 0, offset) + 1


def decoded(data: bytes, where: str, expected: str, *, bom: bool = True) -> str:
    """``data`` as UTF-8 text, or a one-line :class:`AppealInputError` naming the line of the first bad byte.

    Parameters
    ----------
    data : bytes
        The file's bytes.
    where : str
        The file, first in the message.
    expected : str
        What the file should be, the end of the message (``"UTF-8 CSV/TSV text"``).
    bom : bool
        Accept (and drop) a UTF-8 byte-order mark; False refuses it (a file re-saved by another
        program).
    """
    nul = data.find(b"\0")
    if nul >= 0:
        raise AppealInputError(f"{where}:{line_of(data, nul)}: a NUL byte (a binary file, or text in UTF-16?): "
                               f"expected {expected}")
    if data.startswith(b"\xef\xbb\xbf") and not bom:
        raise AppealInputError(f"{where}:1: a byte-order mark: the file was saved again by another program "
                               f"(expected {expected})")
    try:
        return data.decode("utf-8-sig" if bom else "utf-8")
    except UnicodeDecodeError as exc:
        raise AppealInputError(f"{where}:{line_of(data, exc.start)}: not UTF-8 (byte 0x{data[exc.start]:02x}): "
                               f"expected {expected}") from None
