"""ProMP fitting and likelihood; exact DTW against the plain reference; fastdtw if installed."""

import numpy as np
import pytest

from cbgo.services.dynamic_gesture.dtw import (
    TemplateBank,
    compiled_dtw_distances,
    dtw_library,
    dtw_naive,
    fastdtw_backend,
    fastdtw_distances,
)
from cbgo.services.dynamic_gesture.promp import ProMP


def demos(rng, n=12, scale=100.0, noise=3.0):
    out = []
    for _ in range(n):
        length = int(rng.integers(10, 25))
        s = np.linspace(0, 1, length)
        amp = scale * rng.uniform(0.9, 1.1)
        out.append(np.column_stack([amp * s**2 * (3 - 2 * s), 10 * np.sin(np.pi * s),
                                    np.zeros(length), np.zeros(length)])
                   + rng.normal(0, noise, (length, 4)))
    return out


def test_a_promp_mean_follows_the_demonstrations():
    rng = np.random.default_rng(0)
    promp = ProMP.fit(demos(rng))
    mean = promp.mean(20)
    assert mean.shape == (20, 4)
    assert abs(mean[0, 0]) < 6 and abs(mean[-1, 0] - 100) < 6 and abs(mean[10, 1] - 10) < 4


def test_a_promp_likes_its_own_family_more_than_another():
    rng = np.random.default_rng(1)
    promp = ProMP.fit(demos(rng))
    same = demos(rng, n=5)
    other = [d[:, [1, 0, 2, 3]] for d in demos(rng, n=5)]  # the motion along another axis
    assert min(promp.log_likelihood(d) for d in same) > max(
        promp.log_likelihood(d) for d in other)


def test_a_promp_from_two_takes_is_proper_and_survives_serialisation():
    rng = np.random.default_rng(2)
    promp = ProMP.fit(demos(rng, n=2))
    assert np.all(np.linalg.eigvalsh(promp.cov_w) > 0)
    again = ProMP.from_dict(promp.to_dict())
    probe = demos(rng, n=1)[0]
    assert again.log_likelihood(probe) == pytest.approx(promp.log_likelihood(probe))


def test_a_promp_refuses_no_or_mismatched_demonstrations():
    with pytest.raises(ValueError):
        ProMP.fit([])
    with pytest.raises(ValueError):
        ProMP.fit([np.zeros((5, 4)), np.zeros((5, 3))])


def test_exact_dtw_equals_the_plain_reference_for_every_template():
    rng = np.random.default_rng(3)
    for _ in range(25):
        x = np.cumsum(rng.normal(0, 5, (int(rng.integers(1, 30)), 4)), 0)
        templates = [np.cumsum(rng.normal(0, 5, (int(rng.integers(1, 30)), 4)), 0)
                     for _ in range(int(rng.integers(1, 6)))]
        fast = TemplateBank(templates).costs(x)
        reference = [dtw_naive(x, t) for t in templates]
        assert np.allclose(fast, reference, rtol=1e-9, atol=1e-9)


def test_dtw_is_zero_for_a_sequence_and_its_time_stretched_copy():
    x = np.column_stack([np.arange(10.0), np.zeros((10, 3))])
    stretched = np.repeat(x, 2, axis=0)
    assert dtw_library(x, [x, stretched]) == pytest.approx([0.0, 0.0])


@pytest.mark.skipif(fastdtw_backend() is None, reason="fastdtw is not installed")
def test_fastdtw_with_an_integer_norm_approximates_the_exact_distance():
    rng = np.random.default_rng(4)
    x = np.cumsum(rng.normal(0, 5, (20, 4)), 0)
    templates = [np.cumsum(rng.normal(0, 5, (18, 4)), 0) for _ in range(3)]
    exact = dtw_library(x, templates)
    approx = fastdtw_distances(x, templates)
    assert np.all(approx >= exact - 1e-9) and np.all(approx <= exact * 1.5)


@pytest.mark.skipif(fastdtw_backend() != "c", reason="fastdtw's extension is not built")
def test_fastdtw_compiled_exact_dtw_equals_the_plain_reference():
    rng = np.random.default_rng(5)
    for _ in range(10):
        x = np.cumsum(rng.normal(0, 5, (int(rng.integers(2, 25)), 4)), 0)
        templates = [np.cumsum(rng.normal(0, 5, (int(rng.integers(2, 25)), 4)), 0)
                     for _ in range(3)]
        assert np.allclose(compiled_dtw_distances(x, templates), dtw_library(x, templates))
