"""The open-set rule measured beside the model: k-th neighbour distances in the hidden layer."""

import numpy as np

from cbgo.services.static_gesture import openset, train


def test_the_kth_distance_is_the_kth_smallest_euclidean_distance():
    rng = np.random.default_rng(0)
    reference, query = rng.normal(size=(300, 4)), rng.normal(size=(7, 4))
    want = np.sort(np.linalg.norm(query[:, None] - reference[None], axis=-1), 1)[:, 2]
    assert np.allclose(openset.kth_distance(reference, query, 3), want)


def test_frames_far_from_every_training_gesture_are_mostly_novel_training_ones_not():
    options = train.TrainOptions(per_gesture=30, none=30, off_vocabulary=30, hidden=[8],
                                 epochs=2, mmhgr=False, user_gestures=False)
    data = train.build_dataset(options, user=[])
    clf = train.classifier_of(train.fit(data, options), samples=4)
    rule = openset.OpenSet.fit(clf, data.x, data.y, data.names, np.random.default_rng(1))
    known = data.x[np.array(data.names)[data.y] != "none"]
    far = known[:20].copy()
    far[:, 42:] *= 4.0  # every fingertip and palm distance four times a hand's
    assert rule.novel(clf, known).mean() < 0.05
    # not all: tanh units saturate, and a frame far out can land where training frames do
    assert rule.novel(clf, far).mean() > 0.7
