"""report.json (written by `lboost eval`) as Python objects.

    report = landmarkboost.read_report("out/default/report.json")
    report.dataset.query_frames
    for name, method in report.methods.items():
        print(name, method.precision_at_1, method.per_frame.position_error_m.mean())

Every JSON object becomes a Record: a read-only mapping whose keys are also attributes (keys that
are not identifiers, such as "0.1", by indexing only). Lists of numbers become numpy arrays
(float64, or int64 when every entry is an integer); non-finite numbers, which JSON cannot hold,
read as float: null inside a list of numbers, and the strings "inf", "-inf", "nan" anywhere, become
inf, -inf or nan. The reader follows the file: fields it does not know are kept as they are.
"""
import json
import math
import os
from collections.abc import Mapping

import numpy as np

from ._core import Error
from ._path import fspath

_NON_FINITE = {"inf": math.inf, "+inf": math.inf, "-inf": -math.inf, "nan": math.nan,
               "Infinity": math.inf, "-Infinity": -math.inf, "NaN": math.nan}
_INT64 = np.iinfo(np.int64)


class ReportError(Error, ValueError):
    """A file that is not a readable report (landmarkboost.Error, and a ValueError)."""


def _is_number(v):
    return ((isinstance(v, (int, float)) and not isinstance(v, bool)) or v is None
            or (isinstance(v, str) and v in _NON_FINITE))


def _convert(v):
    if isinstance(v, dict):
        return Record(v)
    if isinstance(v, str) and v in _NON_FINITE:
        return _NON_FINITE[v]
    if isinstance(v, list):
        if v and all(_is_number(x) for x in v) and any(x is not None for x in v):
            if all(isinstance(x, int) and _INT64.min <= x <= _INT64.max for x in v):
                return np.array(v, dtype=np.int64)
            try:
                return np.array([math.nan if x is None else _NON_FINITE.get(x, x) for x in v], dtype=np.float64)
            except OverflowError:  # an integer beyond float64's range: the numbers as they are
                pass
        return [_convert(x) for x in v]
    return v


class Record(Mapping):
    """A JSON object: a read-only mapping with attribute access to its keys."""

    def __init__(self, data):
        self._data = {k: _convert(v) for k, v in data.items()}

    def __getitem__(self, key):
        return self._data[key]

    def __iter__(self):
        return iter(self._data)

    def __len__(self):
        return len(self._data)

    def __getattr__(self, name):
        try:
            return self.__dict__["_data"][name]
        except KeyError:
            raise AttributeError(f"no field '{name}' (fields: {', '.join(self._data)})") from None

    def __dir__(self):
        return list(super().__dir__()) + [k for k in self._data if k.isidentifier()]

    def __repr__(self):
        return f"Record({', '.join(self._data)})"


class Report(Record):
    """The whole report: report.dataset, report.methods (name -> Record), and any other top-level
    field of the file as an attribute. report.raw is the JSON as parsed."""

    def __init__(self, data, path=None):
        if not isinstance(data, dict) or not isinstance(data.get("methods"), dict):
            raise ReportError(f"{path or 'report'}: not a LandmarkBoost report (no 'methods' object)")
        super().__init__(data)
        self.__dict__["raw"] = data
        self.__dict__["path"] = path

    def __repr__(self):
        return f"<landmarkboost.Report {self.path or ''}: methods {', '.join(self.methods)}>"


def read_report(path):
    """Reads report.json (path: str, bytes or os.PathLike). Raises OSError for a file that cannot
    be read and landmarkboost.Error, also a ValueError, naming the file for one that is not a
    report: not UTF-8, invalid JSON, nested deeper than Python's recursion limit, or without the
    'methods' object."""
    path = fspath(path, "read_report: path")
    name = os.fsdecode(path)
    with open(path, "rb") as f:
        raw = f.read()
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as e:
        raise ReportError(f"{name}: not UTF-8 text (byte {e.start}: {raw[e.start:e.start + 1]!r})") from None
    try:
        data = json.loads(text)
    except RecursionError:
        raise ReportError(f"{name}: invalid JSON: nested too deeply") from None
    except ValueError as e:  # json.JSONDecodeError, or an integer of more digits than Python converts
        raise ReportError(f"{name}: invalid JSON: {e}") from None
    try:
        return Report(data, name)
    except RecursionError:
        raise ReportError(f"{name}: nested too deeply to read (Python's recursion limit)") from None
