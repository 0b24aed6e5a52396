"""`cbgo train intent` writes to the data directory, and the service serves what it wrote."""

import argparse
from pathlib import Path

from cbgo.services.intent import main as intent_main
from cbgo.services.intent.main import Intent, IntentSettings
from cbgo.testing import FakeBus
from cbgo_tools.intent import train

PACKAGE = Path(intent_main.__file__).parent


def run_trainer(*argv):
    parser = argparse.ArgumentParser()
    train.add_arguments(parser)
    return train.run(parser.parse_args(list(argv)))


def test_without_a_trained_model_the_shipped_one_is_served(tmp_path, monkeypatch):
    monkeypatch.setenv("CBGO_DATA_DIR", str(tmp_path / "data"))
    assert intent_main.served_model_path() == intent_main.default_model_path()
    assert intent_main.default_model_path().is_relative_to(PACKAGE)


def test_train_writes_into_the_data_dir_and_the_service_serves_it(tmp_path, monkeypatch):
    data = tmp_path / "data"
    monkeypatch.setenv("CBGO_DATA_DIR", str(data))
    shipped = {p: p.stat().st_mtime_ns for p in (PACKAGE / "models").iterdir()}

    assert run_trainer("-n", "200", "--test", "50", "--steps", "5") == 0

    written = data / "models" / "intent-ours"
    assert written.with_suffix(".pt").is_file() and written.with_suffix(".json").is_file()
    assert {p: p.stat().st_mtime_ns for p in (PACKAGE / "models").iterdir()} == shipped
    assert intent_main.served_model_path() == written.with_suffix(".json")

    service = Intent(IntentSettings(personal_dir=str(tmp_path / "personal")))
    bus = FakeBus(service)
    try:
        # The trained model's metadata says how it was made: -n 200, not the shipped 8000.
        assert service.engine.model.meta["trained_on"]["samples"] == 200
    finally:
        bus.stop()


def test_other_kinds_go_beside_it_and_are_not_served(tmp_path, monkeypatch):
    monkeypatch.setenv("CBGO_DATA_DIR", str(tmp_path / "data"))
    assert train.default_out("M5") == tmp_path / "data" / "models" / "intent-m5"
    assert intent_main.served_model_path() == intent_main.default_model_path()
