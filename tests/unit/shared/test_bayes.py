"""The variational Bayesian MLP: KL, training, posterior-averaged predictions, save/load."""

import numpy as np
import pytest
import torch

from cbgo import bayes
from cbgo.errors import ConfigError
from cbgo.metrics import balanced_accuracy, expected_calibration_error


def blobs(n=600, seed=0):
    rng = np.random.default_rng(seed)
    centres = np.array([[0, 0], [3, 0], [0, 3]])
    y = rng.integers(0, 3, n)
    return centres[y] + rng.normal(0, 0.7, (n, 2)), y


def test_the_kl_of_a_posterior_equal_to_the_prior_is_zero():
    layer = bayes.BayesLinear(3, 2, prior_sigma=1.0)
    with torch.no_grad():
        layer.w_mu.zero_()
        layer.b_mu.zero_()
        layer.w_rho.fill_(float(np.log(np.e - 1)))  # softplus = 1 = prior sigma
        layer.b_rho.fill_(float(np.log(np.e - 1)))
    assert abs(layer.kl().item()) < 1e-5


def test_the_kl_matches_the_closed_form_for_one_weight():
    layer = bayes.BayesLinear(1, 1, prior_sigma=2.0, bias=False)
    with torch.no_grad():
        layer.w_mu.fill_(1.0)
        layer.w_rho.fill_(float(np.log(np.exp(0.5) - 1)))  # sigma 0.5
    expected = np.log(2.0 / 0.5) + (0.5**2 + 1.0**2) / (2 * 2.0**2) - 0.5
    assert abs(layer.kl().item() - expected) < 1e-5


def test_training_learns_separable_classes_with_calibrated_probabilities():
    x, y = blobs()
    xt, yt = blobs(seed=1)
    model = bayes.BayesMLP(bayes.Architecture(2, [16], 3))
    history = bayes.train(model, x, y, bayes.TrainConfig(epochs=60, batch_size=64, lr=0.02))
    assert history[-1] < history[0]
    probs = bayes.predict_proba(model, xt, samples=16)
    assert np.allclose(probs.sum(1), 1.0)
    assert balanced_accuracy(yt, probs.argmax(1), 3) > 0.9
    assert expected_calibration_error(probs, yt) < 0.08


def test_far_from_the_data_predictions_are_less_certain_than_near_it():
    x, y = blobs()
    model = bayes.BayesMLP(bayes.Architecture(2, [16], 3))
    bayes.train(model, x, y, bayes.TrainConfig(epochs=60, batch_size=64, lr=0.02))
    near = bayes.predict_proba(model, np.array([[3.0, 0.0]]), samples=64)
    between = bayes.predict_proba(model, np.array([[1.5, 1.5]]), samples=64)
    assert near.max() > between.max()


def test_a_saved_model_loads_back_with_its_metadata_and_same_predictions(tmp_path):
    x, y = blobs()
    model = bayes.BayesMLP(bayes.Architecture(2, [8], 3, activation="relu"))
    bayes.train(model, x, y, bayes.TrainConfig(epochs=5))
    std = bayes.Standardizer.fit(x)
    bayes.save(tmp_path / "m", model, {"names": ["a", "b", "c"], "standardizer": std})
    loaded = bayes.load(tmp_path / "m.pt")
    assert loaded.metadata["names"] == ["a", "b", "c"]
    assert np.allclose(loaded.standardizer(x[:3]), std(x[:3]))
    assert np.allclose(bayes.predict_proba(loaded.model, x[:5]), bayes.predict_proba(model, x[:5]))


def one_network_at_a_time(model, x, draws):
    """The reference: each drawn network run on its own, with plain matrix products."""
    out = []
    for s in range(len(draws[0][0])):
        h = x
        for i, (w, b) in enumerate(draws):
            h = model.act(h) if i else h
            h = h @ w[s].T + (b[s] if b is not None else 0.0)
        out.append(h)
    return torch.stack(out)


@pytest.mark.parametrize("activation, bias", [("tanh", True), ("relu", False)])
def test_the_batched_forward_of_drawn_networks_equals_running_them_one_by_one(activation, bias):
    torch.manual_seed(0)
    model = bayes.BayesMLP(bayes.Architecture(5, [7, 4], 3, activation, bias=bias))
    with torch.no_grad():
        for layer in model.layers:
            layer.w_rho.fill_(-1.0)  # sigma ≈ 0.31: the drawn networks differ visibly
        x = torch.randn(2, 6, 5)  # any leading shape: observations × objects
        draws = model.draw(8, torch.Generator().manual_seed(1))
        batched = model.forward_drawn(x, draws)
        reference = one_network_at_a_time(model, x, draws)
    assert batched.shape == (8, 2, 6, 3)
    assert torch.allclose(batched, reference, atol=1e-5)
    assert (reference[0] - reference[1]).abs().max() > 0.1  # the draws are not all alike


def test_draws_follow_the_posterior_and_their_seed():
    layer = bayes.BayesLinear(4, 3)
    with torch.no_grad():
        layer.w_rho.fill_(float(np.log(np.exp(0.5) - 1)))  # sigma 0.5
        layer.b_mu.fill_(2.0)
        w, b = layer.draw(20000, torch.Generator().manual_seed(0))
        same, _ = layer.draw(20000, torch.Generator().manual_seed(0))
        other, _ = layer.draw(20000, torch.Generator().manual_seed(1))
    assert w.shape == (20000, 3, 4) and b.shape == (20000, 3)
    assert torch.allclose(w.mean(0), layer.w_mu, atol=0.02)
    assert torch.allclose(w.std(0), torch.full((3, 4), 0.5), atol=0.02)
    assert torch.allclose(b.mean(0), torch.full((3,), 2.0), atol=0.02)
    assert torch.equal(same, w) and not torch.equal(other, w)


def test_loading_a_broken_model_names_the_problem(tmp_path):
    with pytest.raises(ConfigError, match="cannot load model"):
        bayes.load(tmp_path / "missing")
    (tmp_path / "m.json").write_text('{"format": "other"}')
    torch.save({}, tmp_path / "m.pt")
    with pytest.raises(ConfigError, match="is not a cbgo-bnn/1 model"):
        bayes.load(tmp_path / "m")


def test_an_ensemble_saves_its_members_and_loads_them_back(tmp_path):
    arch = bayes.Architecture(3, [4], 2)
    members = []
    for seed in (1, 2):
        torch.manual_seed(seed)
        members.append(bayes.BayesMLP(arch))
    ensemble = bayes.BayesEnsemble.of(members)
    bayes.save(tmp_path / "e", ensemble, {"members": 2})
    loaded, meta = bayes.load_module(
        tmp_path / "e", lambda m: bayes.BayesEnsemble(bayes.Architecture(**m["architecture"]),
                                                      m["members"]))
    for kept, back in zip(members, loaded.members, strict=True):
        assert torch.equal(kept.layers[0].w_mu, back.layers[0].w_mu)
    assert not torch.equal(loaded.members[0].layers[0].w_mu, loaded.members[1].layers[0].w_mu)


def test_an_ensemble_refuses_no_members_and_mixed_architectures():
    with pytest.raises(ConfigError, match="at least one member"):
        bayes.BayesEnsemble(bayes.Architecture(3, [4], 2), 0)
    with pytest.raises(ConfigError, match="one architecture"):
        bayes.BayesEnsemble.of([bayes.BayesMLP(bayes.Architecture(3, [4], 2)),
                                bayes.BayesMLP(bayes.Architecture(3, [5], 2))])
