"""Hypothesis strategies that damage valid input files the way foreign tools and broken disks do,
and the one assertion of every reader fuzz test: only the project's own error, naming the file."""

from __future__ import annotations

import copy
import math

from hypothesis import strategies as st

#: Values that replace a field: wrong types, non-finite and huge numbers, odd strings, containers.
ODD_SCALARS = st.one_of(
    st.none(), st.booleans(), st.integers(min_value=-(2**70), max_value=2**70),
    st.sampled_from([math.nan, math.inf, -math.inf, 1e308, -1e308, 0.0, -1.0, 1e-320, 0.5]),
    st.floats(allow_nan=True, allow_infinity=True),
    st.text(max_size=12), st.sampled_from(["", " ", "../../etc/passwd", "a\x00b", "images", "1e3", "nan"]),
)
ODD_VALUES = st.recursive(ODD_SCALARS, lambda inner: st.one_of(st.lists(inner, max_size=5),
                                                              st.dictionaries(st.text(max_size=6), inner, max_size=4)),
                          max_leaves=12)


def _paths(obj, prefix=()):
    """Every path (tuple of keys / indices) into a JSON tree, the root excluded."""
    out = []
    if isinstance(obj, dict):
        items = obj.items()
    elif isinstance(obj, list):
        items = enumerate(obj)
    else:
        return out
    for k, v in items:
        out.append(prefix + (k,))
        out.extend(_paths(v, prefix + (k,)))
    return out


def _parent(obj, path):
    for k in path[:-1]:
        obj = obj[k]
    return obj


@st.composite
def mutated_json(draw, valid: dict, max_mutations: int = 3):
    """A deep copy of ``valid`` with 1..max_mutations edits: a key or list item removed, a value replaced
    by an odd value (wrong type, NaN / inf, huge, text, container), or a list truncated / duplicated."""
    doc = copy.deepcopy(valid)
    for _ in range(draw(st.integers(1, max_mutations))):
        paths = _paths(doc)
        if not paths:
            break
        path = draw(st.sampled_from(paths))
        parent = _parent(doc, path)
        key = path[-1]
        op = draw(st.sampled_from(["delete", "replace", "replace", "list"]))
        if op == "delete":
            del parent[key]
        elif op == "replace":
            parent[key] = draw(ODD_VALUES)
        elif isinstance(parent[key], list) and parent[key]:
            lst = parent[key]
            parent[key] = draw(st.sampled_from([lst[:-1], lst + lst[-1:], [], lst[::-1]]))
        else:
            parent[key] = [parent[key]]
    return doc


@st.composite
def damaged_bytes(draw, data: bytes):
    """``data`` truncated, with bytes overwritten, or with a slice deleted / repeated."""
    n = len(data)
    op = draw(st.sampled_from(["truncate", "flip", "splice"]))
    if op == "truncate":
        return data[: draw(st.integers(0, max(n - 1, 0)))]
    if op == "flip":
        buf = bytearray(data)
        for _ in range(draw(st.integers(1, 16))):
            buf[draw(st.integers(0, n - 1))] = draw(st.integers(0, 255))
        return bytes(buf)
    a = draw(st.integers(0, n))
    b = draw(st.integers(a, min(n, a + 64)))
    return data[:a] + (data[a:b] * draw(st.integers(0, 3))) + data[b:]


def assert_own_error(exc: BaseException, allowed: tuple[type[BaseException], ...], *names: str) -> None:
    """The reader raised one of the project's ``allowed`` errors and its message names one of ``names``."""
    assert isinstance(exc, allowed), f"{type(exc).__name__} escaped: {exc}"
    msg = str(exc)
    assert any(n in msg for n in names), f"the message does not name the file ({names}): {msg}"
