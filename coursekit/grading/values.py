"""Plain data in and out of a student's function: arguments decoded, results converted with strict types.

Part of the exercise machinery behind the seed paper's section 4 (students' own GA operators
drive the real systems, and are checked first). Shipped with :mod:`coursekit.grading.runner`
as source text into the grading kernel (see there), so it is self-contained: standard library
and numpy only.

- :func:`decode` turns one encoded argument into the object passed to the function; the
  summative grader passes array arguments in **shared memory** (``{"shared": k, ...}``: the k-th
  file descriptor that came with the call, a ``memfd`` the grading child wrote and reads back
  after the call, see :mod:`coursekit.grading.executor`), so whether the function changed them
  is seen from outside the kernel.
- :func:`convert` turns a result into plain data (:class:`BadOutput` for anything else).
- :func:`changed` compares an argument as it was after a call with what was sent.
"""

from __future__ import annotations

import copy
import json
import math
import mmap

import numpy as np

_INT_TYPES = tuple({np.dtype(c).type for c in "bBhHiIlLqQ"})


class BadOutput(Exception):
    """The function returned something that is not the plain data the check asks for."""


def library_attr(path):
    """``"coursekit.pictures.genome:Genome"`` -> that attribute; only coursekit's own modules."""
    import importlib

    module, _, attr = path.partition(":")
    if not (module == "coursekit" or module.startswith("coursekit.")) or not attr:
        raise ValueError(f"cases may only name coursekit attributes, got {path!r}")
    obj = importlib.import_module(module)
    for part in attr.split("."):
        obj = getattr(obj, part)
    return obj


def decode(value, seed, shared=()):
    """Turn one encoded argument into the Python object passed to the student function.

    Encodings: ``{"rng": true}`` (a generator seeded with ``seed``), ``{"ndarray": ..., "dtype":
    ...}``, ``{"shared": k, "dtype": ..., "shape": [...]}`` (an array over ``shared[k]``, a
    writable shared mapping: what the function writes there, the grading child sees),
    ``{"object": "module:Class", "json": text}`` (``Class.from_json(text)``, for genomes
    and creatures), ``{"function": "module:name"}`` (a library function, e.g. an ODE right-hand
    side), or a plain JSON value.
    """
    if isinstance(value, dict):
        if value.get("rng") is True:
            return np.random.default_rng(seed)
        if "shared" in value:
            return np.frombuffer(shared[value["shared"]], dtype=np.dtype(value["dtype"])).reshape(value["shape"])
        if "ndarray" in value:
            return np.array(value["ndarray"], dtype=np.dtype(value["dtype"]))
        if "object" in value:
            return library_attr(value["object"]).from_json(value["json"])
        if "function" in value:
            return library_attr(value["function"])
        raise ValueError(f"unknown encoded argument {sorted(value)}")
    return copy.deepcopy(value)  # a function that edits its list argument must not edit the case


def encode_array(a):
    """Encode a numpy array as plain data (the inverse of :func:`decode`)."""
    return {"ndarray": a.tolist(), "dtype": str(a.dtype)}


_REAL_TYPES = (int, float, bool) + _INT_TYPES + tuple({np.dtype(c).type for c in "efdg?"})


def _array(out, what, max_len):
    if type(out) in (list, tuple):
        # a list or tuple of plain numbers is what an array holds: accepted as one (exact types only,
        # so an object with a rigged __eq__ or __float__ is not read as a number)
        if len(out) > max_len:
            raise BadOutput(f"{what} has {len(out)} values, far more than the {max_len} allowed")
        if not all(type(v) in _REAL_TYPES for v in out):
            bad = next(v for v in out if type(v) not in _REAL_TYPES)
            raise BadOutput(f"{what} is a {type(out).__name__} holding a {type(bad).__name__}; expected numbers: "
                            "return np.array([...]) of floats")
        out = np.array(out, dtype=np.float64 if any(type(v) not in (int, bool) + _INT_TYPES for v in out) else np.int64)
    elif type(out) is not np.ndarray:
        how = "result.detach().cpu().numpy()" if type(out).__module__.startswith("torch") else "np.asarray(result, dtype=float)"
        raise BadOutput(f"{what} has type {type(out).__name__}; expected a numpy array (np.ndarray): convert it with {how}")
    if out.ndim != 1:
        fix = " (flatten it with result.ravel())" if out.size <= max_len and out.ndim > 1 else ""
        raise BadOutput(f"{what} has shape {out.shape}; expected a 1-D array{fix}")
    if out.dtype.kind not in "biuf":
        raise BadOutput(f"{what} has dtype {out.dtype}; expected numbers (bool, int or float): convert it with "
                        "result.astype(float)")
    if out.size > max_len:
        raise BadOutput(f"{what} has {out.size} values, far more than the {max_len} allowed")
    if out.dtype.kind == "b":
        out = out.astype(np.int64)
    values = out.tolist()
    if out.dtype.kind == "f" and not all(math.isfinite(v) for v in values):
        raise BadOutput(f"{what} contains NaN or infinity")
    return values


def _json_text(out, what, max_len):
    """An object with ``to_json()`` (a genome, a creature) or a plain JSON value, as JSON text."""
    if hasattr(type(out), "to_json"):
        text = out.to_json()
        if type(text) is not str:
            raise BadOutput(f"{what}.to_json() returned {type(text).__name__}; expected str")
    else:
        try:
            text = json.dumps(out, allow_nan=False)
        except (TypeError, ValueError) as exc:
            raise BadOutput(f"{what} has type {type(out).__name__}, which is not plain data ({exc})") from None
    if len(text) > max_len:
        raise BadOutput(f"{what} is {len(text)} characters of JSON, far more than the {max_len} allowed")
    try:
        json.loads(text)
    except ValueError:
        raise BadOutput(f"{what} did not serialise to valid JSON") from None
    return text


def convert(kind, out, max_len):
    """Convert one call's result to plain data with strict type checks, or raise :class:`BadOutput`.

    Args:
        kind: ``"indices"`` (1-D integer array or list/tuple of ints), ``"array"`` (1-D numpy
            array of numbers, or a list/tuple of plain numbers), ``"array_pair"`` (a tuple or list of two such arrays), ``"json"``
            (an object with ``to_json()`` or plain JSON data) or ``"json_pair"`` (two of those).
        out: the function's return value.
        max_len: largest number of values accepted (characters of JSON text for the json kinds).
    Returns:
        a list of ints / floats, or a list of two such lists; JSON text, or a list of two.
    """
    if kind == "indices":
        if type(out) is np.ndarray:
            if out.ndim != 1 or out.dtype.kind not in "iu":
                raise BadOutput(f"returned an array of shape {out.shape} and dtype {out.dtype}; expected a 1-D array of integer indices")
            if out.size > max_len:
                raise BadOutput(f"returned {out.size} indices, far more than the {max_len} allowed")
            return [int(v) for v in out.tolist()]
        if type(out) in (list, tuple):
            if len(out) > max_len:
                raise BadOutput(f"returned {len(out)} indices, far more than the {max_len} allowed")
            values = []
            for i, v in enumerate(out):
                if type(v) is not int and type(v) not in _INT_TYPES:
                    raise BadOutput(f"element {i} of the result has type {type(v).__name__}; indices must be plain integers")
                values.append(int(v))
            return values
        raise BadOutput(f"returned a value of type {type(out).__name__}; expected a sequence of integer indices (list or numpy array)")
    if kind == "array":
        return _array(out, "the result", max_len)
    if kind == "json":
        return _json_text(out, "the result", max_len)
    if kind in ("array_pair", "json_pair"):
        if type(out) not in (tuple, list) or len(out) != 2:
            n = f" of length {len(out)}" if type(out) in (tuple, list) else ""
            raise BadOutput(f"returned a {type(out).__name__}{n}; expected a pair (child1, child2)")
        one = _array if kind == "array_pair" else _json_text
        return [one(out[0], "child 1", max_len), one(out[1], "child 2", max_len)]
    raise ValueError(f"unknown output kind {kind!r}")


def _after(arg, encoded, max_len):
    """An argument as it is after the call, to show whether the function modified it."""
    if type(arg) is np.ndarray:
        return encode_array(arg)
    if isinstance(encoded, dict) and "object" in encoded:
        try:
            return {"json": _json_text(arg, "the argument", max_len)}
        except BadOutput:
            raise
        except Exception:  # the function broke it (a creature with None among its nodes): it changed
            return {"json": "null"}
    return None


def changed(after, encoded) -> bool:
    """Did a call change one argument? ``encoded``: the argument as sent; ``after``: its entry of ``inputs_after``."""
    if after is None:
        return False
    if "json" in after:
        return not (isinstance(encoded, dict) and "json" in encoded) or json.loads(after["json"]) != json.loads(encoded["json"])
    return after != encoded




def share(value):
    """The bytes and shape of an encoded array argument, for shared memory; None when it is not one
    (or is empty: zero bytes cannot be mapped, and an empty array has nothing to change)."""
    if not (isinstance(value, dict) and set(value) == {"ndarray", "dtype"}):
        return None
    a = np.array(value["ndarray"], dtype=np.dtype(value["dtype"]))
    return (a.tobytes(), list(a.shape)) if a.nbytes else None


def unshare(data, encoded):
    """The encoded array argument ``encoded`` with the contents ``data`` read back from shared memory."""
    return {"ndarray": np.frombuffer(data, dtype=np.dtype(encoded["dtype"])).tolist(), "dtype": encoded["dtype"]}


def map_shared(fds, sizes):
    """Writable shared mappings of the file descriptors that came with a call (then closed)."""
    import os

    maps = []
    try:
        for fd, size in zip(fds, sizes):
            maps.append(mmap.mmap(fd, size))
    finally:
        for fd in fds:
            os.close(fd)
    return maps
