"""volume.surroundings: the views capture.blurred_views calls blurred leave the work while enough stay."""

from __future__ import annotations

from dataclasses import dataclass
from types import SimpleNamespace

from volume import surroundings as su


@dataclass(frozen=True)
class _Work:
    refs: tuple
    scans: tuple


def _work(n: int = 10) -> _Work:
    return _Work(tuple(SimpleNamespace(name=f"v{i}", index=i) for i in range(n)), tuple(range(n)))


def test_blurred_views_leave_the_work_and_their_plates():
    rec = {"per_view": [{"blur": {"blurred": i in (3, 8)}} for i in range(10)]}
    w, plates, out = su._without_blurred(_work(), list("abcdefghij"), rec)
    assert [r.name for r in w.refs] == [f"v{i}" for i in range(10) if i not in (3, 8)]
    assert w.scans == (0, 1, 2, 4, 5, 6, 7, 9) and plates == list("abcefghj")
    assert out["blurred_left_out"] == ["v3", "v8"]


def test_blurred_views_are_kept_by_default_and_said():
    """--blurred-views keep (the default): the work as it was, the record names them."""
    work = _work()
    rec = {"per_view": [{"blur": {"blurred": i in (3, 8)}} for i in range(10)]}
    w, plates, out = su._without_blurred(work, list("abcdefghij"), rec, leave_out=False)
    assert w is work and plates == list("abcdefghij") and out["blurred_kept"] == ["v3", "v8"]


def test_too_many_blurred_views_are_kept_and_said():
    """Fewer than BLURRED_KEEP of the views would stay: all kept, the record names them."""
    work = _work()
    rec = {"per_view": [{"blur": {"blurred": i < 5}} for i in range(10)]}
    w, plates, out = su._without_blurred(work, list("abcdefghij"), rec)
    assert w is work and plates == list("abcdefghij")
    assert out["blurred_kept"] == [f"v{i}" for i in range(5)] and "blurred_left_out" not in out


def test_no_blurred_view_changes_nothing():
    work, rec = _work(), {"per_view": [{"blur": {"blurred": False}} for _ in range(10)]}
    assert su._without_blurred(work, list("abcdefghij"), rec) == (work, list("abcdefghij"), rec)
