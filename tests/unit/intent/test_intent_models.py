"""The models output valid probabilities; cbgo's model ignores object order, M1-M5 do not."""

import numpy as np
import pytest
import torch

from cbgo.services.intent import datasets, models
from cbgo.services.intent.decide import decide_arrays, joint_correct
from cbgo.services.intent.models import (
    SLOT_KINDS,
    Batch,
    IntentDraws,
    OursModel,
    SlotModel,
    focus_field,
    map_gestures,
    slot_features,
)


def permuted(batch: Batch, rng) -> tuple[Batch, np.ndarray]:
    """The same observations with each scene's objects in a random order."""
    order = np.stack([np.concatenate([rng.permutation(int(m.sum())), np.arange(int(m.sum()),
                                                                              len(m))])
                      for m in batch.mask])
    out = batch.subset(np.arange(batch.n))
    rows = np.arange(batch.n)[:, None]
    for name in ("obj_type", "obj_state", "obj_held", "obj_hidden", "obj_pos"):
        setattr(out, name, getattr(batch, name)[rows, order])
    return out, order


def test_the_shipped_model_outputs_a_joint_distribution_over_real_objects(shipped):
    ds = datasets.make("D4", 120, seed=21)
    pred = shipped.predict(Batch.from_dataset(ds), samples=8)
    assert np.allclose(pred.joint.sum((1, 2)), 1.0)
    assert np.allclose(pred.p_action.sum(1), 1.0) and np.allclose(pred.p_object.sum(1), 1.0)
    empty = ~Batch.from_dataset(ds).mask
    assert np.all(pred.joint[empty] == 0.0)
    assert np.allclose(pred.p_action, pred.joint.sum(1))


def test_the_shipped_model_reads_fresh_d5_scenes(shipped):
    ds = datasets.make("D5", 400, seed=22)
    batch = Batch.from_dataset(ds)
    pred = shipped.predict(batch, samples=16)
    action, slot, _ = decide_arrays(pred.joint, ds.feasible, batch.mask)
    assert joint_correct(action, slot, ds.action, ds.target).mean() > 0.98


def test_cbgos_model_is_invariant_to_the_order_of_objects(shipped, tiny):
    m5 = tiny[1]
    batch = Batch.from_dataset(datasets.make("D4", 50, seed=23))
    shuffled, order = permuted(batch, np.random.default_rng(0))
    a, b = shipped.predict(batch, samples=4), shipped.predict(shuffled, samples=4)
    assert np.allclose(a.p_action, b.p_action, atol=1e-6)
    assert np.allclose(a.p_object[np.arange(50)[:, None], order], b.p_object, atol=1e-6)
    m_a, m_b = m5.predict(batch, samples=4), m5.predict(shuffled, samples=4)
    assert not np.allclose(m_a.p_action, m_b.p_action, atol=1e-3)


def test_cbgos_model_takes_any_number_of_objects_and_no_focus(shipped):
    ds = datasets.make("D4", 20, seed=24)
    batch = Batch.from_dataset(ds)
    wide = Batch.concat([batch], k=12)
    assert np.allclose(shipped.predict(wide, samples=4).p_action,
                       shipped.predict(batch, samples=4).p_action, atol=1e-6)
    blind = batch.subset(np.arange(batch.n))
    blind.has_focus[:] = False
    pred = shipped.predict(blind, samples=4)
    assert np.allclose(pred.joint.sum((1, 2)), 1.0)
    sharp = shipped.predict(batch, samples=4).p_object.max(1).mean()
    assert pred.p_object.max(1).mean() < sharp


def test_slot_models_read_the_papers_inputs():
    ds = datasets.make("D4", 30, seed=25)
    batch = Batch.from_dataset(ds)
    widths = {kind: slot_features(kind, batch).shape[1] for kind in SLOT_KINDS}
    assert widths == {"M1": 9, "M2": 16, "M3": 11, "M4": 18, "M5": 25}
    field = focus_field(batch)
    assert (field.argmax(1) == ds.target).mean() > 0.9
    assert np.all(field[~batch.mask] == 0.0)
    with pytest.raises(Exception, match="unknown slot model"):
        SlotModel("M9")


def test_trained_models_save_and_load_with_the_same_predictions(tmp_path, tiny):
    ours, m5 = tiny
    batch = Batch.from_dataset(datasets.make("D4", 20, seed=26))
    ours.save(tmp_path / "ours")
    m5.save(tmp_path / "m5")
    again = OursModel.load(tmp_path / "ours.pt")
    assert again.meta["model_id"] == "intent-ours-test"
    assert np.allclose(again.predict(batch).joint, ours.predict(batch).joint)
    assert np.allclose(SlotModel.load(tmp_path / "m5").predict(batch).p_action,
                       m5.predict(batch).p_action)
    with pytest.raises(Exception, match="not 'ours'"):
        OursModel.load(tmp_path / "m5")


def inputs(model: OursModel, batch: Batch) -> list[torch.Tensor]:
    t = models._tensors(batch, model.context_standardizer)
    return [t["obj"], t["act"], t["ctx"], t["mask"]]


def stacked(draws: list[IntentDraws]) -> IntentDraws:
    """One set of S drawn networks from S sets of one."""
    def layers(per_draw):
        return [(torch.cat([d[i][0] for d in per_draw]), torch.cat([d[i][1] for d in per_draw]))
                for i in range(len(per_draw[0]))]
    return IntentDraws(layers([d.scorer for d in draws]), layers([d.actor for d in draws]))


def test_the_batched_posterior_average_equals_the_loop_over_one_sample_forwards(shipped):
    # The loop is how predictions were made before: one forward (one shared weight sample,
    # drawn from torch's global generator) per posterior sample. Seeding the global generator
    # alike makes `draw(1)` draw the same weights, so both paths see the same networks.
    batch = Batch.from_dataset(datasets.make("D4", 12, seed=27))
    x, seeds = inputs(shipped, batch), range(6)
    with torch.no_grad():
        loop = []
        for seed in seeds:
            torch.manual_seed(seed)
            loop.append(torch.exp(shipped.net(*x)))
        draws = []
        for seed in seeds:
            torch.manual_seed(seed)
            draws.append(shipped.net.draw(1))
        batched = torch.exp(shipped.net.forward_drawn(*x, stacked(draws)))
    assert batched.shape == (6, *loop[0].shape)
    assert torch.allclose(batched, torch.stack(loop), atol=1e-6)
    assert (loop[0] - loop[1]).abs().max() > 1e-3  # the sampled networks do differ


def test_a_prediction_sees_the_same_networks_in_every_chunk_and_follows_its_seed(
        shipped, monkeypatch):
    batch = Batch.from_dataset(datasets.make("D4", 40, seed=28))
    whole = shipped.predict(batch, samples=8)
    monkeypatch.setattr(models, "PREDICT_ROWS", 8 * batch.obj_type.shape[1] * 3)
    chunked = shipped.predict(batch, samples=8)  # 14 chunks of at most 3 observations
    assert np.allclose(chunked.joint, whole.joint, atol=1e-6)
    assert np.abs(shipped.predict(batch, samples=8, seed=1).joint - whole.joint).max() > 1e-4
    draws = shipped.net.draw(8, torch.Generator().manual_seed(0))
    with torch.no_grad():
        mean = torch.exp(shipped.net.forward_drawn(*inputs(shipped, batch), draws)).mean(0)
    assert np.allclose(whole.joint, mean.numpy(), atol=1e-6)


def test_gesture_names_map_by_name_ignoring_unknown_ones():
    vocab = ["swipe_up", "grab", "point"]
    g = map_gestures(["grab", "pinch", "point"], [0.6, 0.9, 0.2], vocab)
    assert np.allclose(g, [0.0, 0.75, 0.25])
    assert not map_gestures(["wave"], [1.0], vocab).any()
