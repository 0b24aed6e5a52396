"""`cbgo bench intent-check --timing`: the cost of one inference."""

from argparse import Namespace

from cbgo_tools.intent import evaluate


def test_timing_prints_the_median_of_a_prediction_and_of_a_whole_inference(capsys):
    args = Namespace(model=None, n=10, repaired=0, seed=5000, samples=4, timing=3)
    assert evaluate.run(args) == 0
    lines = capsys.readouterr().out.splitlines()
    assert "4 posterior samples" in lines[0] and "3 repeats" in lines[0]
    assert [line.split(":")[0].strip() for line in lines[1:]] == ["predict", "infer"]


def test_timing_times_every_repeat_of_both(shipped):
    engine = evaluate.IntentEngine(shipped, evaluate.SERVICE_DECISION, None, 4)
    times = evaluate.time_inference(engine, evaluate.CHECKS[0], 5)
    assert set(times) == {"predict", "infer"}
    assert all(len(ms) == 5 and (ms > 0).all() for ms in times.values())
