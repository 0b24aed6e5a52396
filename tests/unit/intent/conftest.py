"""Intent test fixtures: the shipped model, a tiny trained model, single-threaded torch."""

import pytest
import torch

from cbgo.services.intent import datasets
from cbgo.services.intent.main import default_model_path
from cbgo.services.intent.models import Batch, OursModel, SlotModel, train_config


@pytest.fixture(scope="session", autouse=True)
def one_thread():
    # Tiny networks on shared 2-core machines: more threads only add contention.
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(threads)


@pytest.fixture(scope="session")
def shipped():
    return OursModel.load(default_model_path())


@pytest.fixture(scope="session")
def small_d4():
    return datasets.make("D4", 300, 7)


@pytest.fixture(scope="session")
def tiny(small_d4):
    """cbgo's model and M5 after a very short training (shapes and plumbing, not accuracy)."""
    batch = Batch.from_dataset(small_d4)
    ours = OursModel()
    ours.fit(batch, small_d4.action, small_d4.target, train_config(len(small_d4), steps=60))
    ours.meta.update(gestures=small_d4.meta["gestures"], users=small_d4.meta["users"],
                     cell_size_m=small_d4.meta["cell_size_m"], model_id="intent-ours-test")
    m5 = SlotModel("M5")
    m5.fit(batch, small_d4.action, train_config(len(small_d4), steps=60))
    return ours, m5
