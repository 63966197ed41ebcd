"""``lopcook.memory.small_pages``: numpy's huge-page advice is off inside the block, restored after
it, and left alone where the user set ``$NUMPY_MADVISE_HUGEPAGE``; the CLI cooks inside it."""

from __future__ import annotations

import pytest

from lopcook.memory import small_pages

setter = pytest.importorskip("numpy._core.multiarray")._set_madvise_hugepage


def current() -> bool:
    state = setter(True)
    setter(state)
    return bool(state)


@pytest.mark.parametrize("before", [True, False])
def test_off_inside_and_restored(monkeypatch, before):
    monkeypatch.delenv("NUMPY_MADVISE_HUGEPAGE", raising=False)
    old = setter(before)
    try:
        with small_pages():
            assert current() is False
            with small_pages():  # nested: still off, and the outer block's state comes back
                assert current() is False
            assert current() is False
        assert current() is before
        with pytest.raises(RuntimeError), small_pages():
            raise RuntimeError("restored on an exception too")
        assert current() is before
    finally:
        setter(old)


def test_user_choice_kept(monkeypatch):
    monkeypatch.setenv("NUMPY_MADVISE_HUGEPAGE", "1")
    old = setter(True)
    try:
        with small_pages():
            assert current() is True
    finally:
        setter(old)


def test_cli_cooks_inside(monkeypatch, tmp_path):
    """The command runs with the advice off (observed from inside the cook's ingest)."""
    import lopcook.api as api
    from lopcook.cli import main

    monkeypatch.delenv("NUMPY_MADVISE_HUGEPAGE", raising=False)
    seen = []
    real = api._load  # the ingest entry the cook calls (lopcook.ingest.load)

    def spy(*a, **k):
        seen.append(current())
        return real(*a, **k)

    monkeypatch.setattr(api, "_load", spy)
    src = tmp_path / "t.obj"
    src.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 2 3 4\nf 1 4 3\n")
    old = setter(True)
    try:
        assert main(["cook", str(src), "-o", str(tmp_path / "t.lop"), "-q"]) == 0
        assert current() is True
    finally:
        setter(old)
    assert seen == [False]
    assert (tmp_path / "t.lop").stat().st_size > 0
