"""The set listing read with sqlite3 (workbench.store_read) against the Store's, which runs it through SQLAlchemy."""

import sqlite3

import pytest

from tests.core.test_store import a_set
from workbench import store_read
from workbench.errors import StoreError
from workbench.store import Store


@pytest.fixture
def url(tmp_path):
    url = f"sqlite:///{tmp_path}/w.db"
    store = Store(url)
    for serial, bias in (("U1", 0.01), ("U2", 0.02), ("U1", 0.03)):  # U1 has two versions
        store.add_set(a_set(serial, bias))
    store.approve(store.list_sets("U2")[0].id, "ops", "checked")
    return url


def test_the_sqlite_listing_is_the_stores(url, monkeypatch):
    expected = {serial: Store(url).list_sets(serial) for serial in (None, "U1", "U2", "U3")}
    monkeypatch.setattr(Store, "list_sets", None)  # read without the Store, or fail
    for serial, infos in expected.items():
        assert store_read.list_sets(serial, url) == (url, infos)
    assert [i.version for i in expected["U1"]] == [2, 1] and expected["U2"][0].approved_by == "ops"
    assert len(expected[None]) == 3 and expected["U3"] == []


def test_a_store_the_sqlite_read_cannot_take_goes_to_the_store(url, tmp_path):
    with sqlite3.connect(url.removeprefix("sqlite:///")) as con:  # an older schema revision
        con.execute(f"UPDATE {store_read.VERSION_TABLE} SET version_num = '0000'")
    with pytest.raises(StoreError, match="schema revision 0000, this version needs"):
        store_read.list_sets(None, url)
    new = f"sqlite:///{tmp_path}/new.db"  # no store yet: created by the Store, then empty
    assert store_read.list_sets(None, new) == (new, []) and (tmp_path / "new.db").is_file()
    memory = "sqlite://"
    assert store_read.list_sets(None, memory) == (memory, [])
