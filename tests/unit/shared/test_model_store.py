"""cbgo.model_store: which model is served, and when its files changed."""

import os

from cbgo.model_store import ModelStore


def write(base, text="x", suffixes=(".pt", ".json")):
    base.parent.mkdir(parents=True, exist_ok=True)
    for s in suffixes:
        (base.with_suffix(s) if s else base).write_text(text)


def test_the_configured_model_wins_then_the_users_once_complete_then_the_shipped(tmp_path):
    shipped, user = tmp_path / "pkg" / "m", tmp_path / "data" / "m"
    store = ModelStore(shipped, user, (".pt", ".json"))
    assert store.path() == shipped
    write(user, suffixes=(".pt",))  # the trainer is half-way: not the user's model yet
    assert store.path() == shipped
    write(user)
    assert store.path() == user
    store.configured = str(tmp_path / "elsewhere")
    assert store.path() == tmp_path / "elsewhere"


def test_a_change_in_size_or_time_or_a_move_is_seen_and_served_clears_it(tmp_path):
    shipped, user = tmp_path / "pkg" / "m.json", tmp_path / "data" / "m.json"
    write(shipped, suffixes=("",))
    store = ModelStore(shipped, user)
    store.served(*store.snapshot())
    assert not store.changed()
    shipped.write_text("longer")
    assert store.changed()
    store.served(*store.snapshot())
    stat = shipped.stat()
    os.utime(shipped, ns=(stat.st_atime_ns, stat.st_mtime_ns + 10**9))
    assert store.changed()
    store.served(*store.snapshot())
    write(user, suffixes=("",))  # the user's first trained model: the choice moves
    assert store.changed() and store.snapshot()[0] == user
