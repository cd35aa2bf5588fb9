"""Path arguments of the package's functions: str, bytes or os.PathLike, nothing else (open() would
take an int for a file descriptor, str() would make a file name of any object)."""
import os


def fspath(path, where):
    """os.fspath(path); TypeError naming `where` for any other type than str, bytes and
    os.PathLike, ValueError for a path with a NUL character (which the OS cannot take)."""
    if not isinstance(path, (str, bytes, os.PathLike)):
        raise TypeError(f"{where}: expected a path (str, bytes or os.PathLike); got {type(path).__name__} {path!r:.60}")
    p = os.fspath(path)
    if ("\0" if isinstance(p, str) else b"\0") in p:
        raise ValueError(f"{where}: the path {p!r:.60} holds a NUL character")
    return p
