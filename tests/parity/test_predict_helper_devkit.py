"""nuparquet.devkit.prediction.PredictHelper against nuscenes-devkit 1.2.0's `nuscenes.prediction.helper.PredictHelper`
on the devkit's own NuScenes over the same dataroot: every public method, on the synthetic set, the irregular profile
(and its version without annotations), the irregular JSON layouts and the real extract, for every agent of a few
samples (each scene's first, middle and last keyframe, and the samples of one-annotation tracks), every track's first
and last annotation, seconds 0, 0.3, 0.5, 3, 6, 100, both frames and both `just_xy`.

Equality is exact (`np.array_equal` with shape and dtype, records `==`, NaN where the devkit gives NaN): the helper
replays the devkit's arithmetic through the same BLAS calls numpy makes for one item (the module's docstring), so no
rounding can differ on the machine that runs both."""

from __future__ import annotations

import numpy as np
import pytest
from pyquaternion import Quaternion

from devkit_pairs import open_pair
from nuparquet.devkit.prediction import PredictHelper
from nuparquet.devkit.prediction import helper as our_module

SECONDS = (0, 0.3, 0.5, 3, 6, 100)


@pytest.fixture(scope="module", params=["synth", "irregular", "layouts", "extract"])
def helpers(request, devkit):
    from nuscenes.prediction import helper as their_module

    pair = open_pair(request, devkit, request.param)
    return pair, PredictHelper(pair.ours), their_module.PredictHelper(pair.theirs)


def chosen_samples(nusc) -> list[str]:
    """A scene's first, middle and last keyframes of every scene, and the samples of one-annotation tracks."""
    tokens = []
    for scene in nusc.scene:
        chain = [scene["first_sample_token"]]
        while nusc.get("sample", chain[-1])["next"]:
            chain.append(nusc.get("sample", chain[-1])["next"])
        tokens += [chain[0], chain[len(chain) // 2], chain[-1]]
    single = [i for i in nusc.instance if i["nbr_annotations"] == 1]
    tokens += [nusc.get("sample_annotation", i["first_annotation_token"])["sample_token"] for i in single]
    return list(dict.fromkeys(tokens))


def same(ours, theirs) -> bool:
    if isinstance(theirs, np.ndarray):
        return (isinstance(ours, np.ndarray) and ours.shape == theirs.shape and ours.dtype == theirs.dtype
                and np.array_equal(ours, theirs))
    if isinstance(theirs, (float, np.floating)) and np.isnan(theirs):
        return bool(np.isnan(ours))
    return ours == theirs


def test_future_and_past_of_every_agent_of_the_chosen_samples(helpers):
    pair, ours, theirs = helpers
    samples = chosen_samples(pair.theirs)
    compared = 0
    for sample in samples:
        for seconds in SECONDS:
            for in_agent_frame in (False, True):
                for just_xy in (True, False):
                    for method in ("get_future_for_sample", "get_past_for_sample"):
                        got = getattr(ours, method)(sample, seconds, in_agent_frame, just_xy=just_xy)
                        want = getattr(theirs, method)(sample, seconds, in_agent_frame, just_xy=just_xy)
                        assert list(got) == list(want)
                        for instance in want:
                            assert same(got[instance], want[instance]), (method, sample, instance, seconds)
                            compared += 1
    assert compared > 0


def test_first_and_last_annotation_of_every_track(helpers):
    pair, ours, theirs = helpers
    shapes, lengths = set(), set()
    # the extract's 900-odd tracks: its one-annotation tracks and the first 60 others keep the test short
    instances = [i for i in pair.theirs.instance if i["nbr_annotations"] == 1] + pair.theirs.instance[:60]
    for instance in (instances if pair.name == "extract" else pair.theirs.instance):
        lengths.add(instance["nbr_annotations"])
        for end in ("first_annotation_token", "last_annotation_token"):
            sample = pair.theirs.get("sample_annotation", instance[end])["sample_token"]
            token = instance["token"]
            assert ours.get_sample_annotation(token, sample) == theirs.get_sample_annotation(token, sample)
            for seconds in (0.5, 3, 100):
                for in_agent_frame in (False, True):
                    for just_xy in (True, False):
                        for method in ("get_future_for_agent", "get_past_for_agent"):
                            got = getattr(ours, method)(token, sample, seconds, in_agent_frame, just_xy=just_xy)
                            want = getattr(theirs, method)(token, sample, seconds, in_agent_frame, just_xy=just_xy)
                            assert same(got, want), (method, token, sample, seconds, in_agent_frame, just_xy)
                            if just_xy:
                                shapes.add(want.shape)
            for method in ("get_velocity_for_agent", "get_heading_change_rate_for_agent",
                           "get_acceleration_for_agent"):
                for max_time_diff in (1.5, 0.1):
                    got = getattr(ours, method)(token, sample, max_time_diff=max_time_diff)
                    want = getattr(theirs, method)(token, sample, max_time_diff=max_time_diff)
                    assert same(got, want), (method, token, sample, max_time_diff, got, want)
    assert 1 in lengths  # a track of one annotation
    assert (0,) in shapes  # the devkit's empty window: np.array([]) of shape (0,), not (0, 2)


def test_rates_annotation_lists_and_map_names_of_the_chosen_samples(helpers):
    pair, ours, theirs = helpers
    rates = []
    for sample in chosen_samples(pair.theirs):
        assert ours.get_annotations_for_sample(sample) == theirs.get_annotations_for_sample(sample)
        assert ours.get_map_name_from_sample_token(sample) == theirs.get_map_name_from_sample_token(sample)
        for record in theirs.get_annotations_for_sample(sample):
            for method in ("get_velocity_for_agent", "get_heading_change_rate_for_agent",
                           "get_acceleration_for_agent"):
                got = getattr(ours, method)(record["instance_token"], sample)
                want = getattr(theirs, method)(record["instance_token"], sample)
                assert same(got, want), (method, record["token"], got, want)
                rates.append(want)
    assert any(np.isnan(r) for r in rates) and any(not np.isnan(r) for r in rates)


def test_the_devkits_errors(helpers):
    pair, ours, theirs = helpers
    record = pair.theirs.sample_annotation[0]
    for helper in (ours, theirs):
        with pytest.raises(ValueError, match="must be non-negative"):
            helper.get_future_for_agent(record["instance_token"], record["sample_token"], -1, False)
        with pytest.raises(KeyError):
            helper.get_sample_annotation(record["instance_token"], "no such sample")
        with pytest.raises(KeyError):
            helper.get_past_for_sample("no such sample", 3, False)


def test_the_devkits_own_helper_runs_on_our_nuscenes(helpers, devkit):
    from nuscenes.prediction.helper import PredictHelper as TheirHelper

    pair, ours, theirs = helpers
    on_ours = TheirHelper(pair.ours)
    for sample in chosen_samples(pair.theirs)[:4]:
        for in_agent_frame in (False, True):
            got = on_ours.get_future_for_sample(sample, 6, in_agent_frame)
            want = theirs.get_future_for_sample(sample, 6, in_agent_frame)
            assert list(got) == list(want) and all(same(got[k], want[k]) for k in want)
        for record in theirs.get_annotations_for_sample(sample):
            assert same(on_ours.get_acceleration_for_agent(record["instance_token"], sample),
                        theirs.get_acceleration_for_agent(record["instance_token"], sample))


def test_a_version_without_annotations(request, devkit):
    from nuscenes.prediction.helper import PredictHelper as TheirHelper

    pair = open_pair(request, devkit, "irregular_empty")
    ours, theirs = PredictHelper(pair.ours), TheirHelper(pair.theirs)
    for sample in chosen_samples(pair.theirs):
        assert ours.get_annotations_for_sample(sample) == theirs.get_annotations_for_sample(sample) == []
        for method in ("get_future_for_sample", "get_past_for_sample"):
            assert getattr(ours, method)(sample, 6, True) == getattr(theirs, method)(sample, 6, True) == {}
        assert ours.get_map_name_from_sample_token(sample) == theirs.get_map_name_from_sample_token(sample)


def test_the_module_functions_are_the_devkits():
    from nuscenes.eval.common.utils import quaternion_yaw
    from nuscenes.prediction import helper as their_module

    rng = np.random.default_rng(37)
    quaternions = rng.normal(size=(500, 4))
    quaternions[:250, 1:3] = 0.0  # rotations about z, as every nuScenes box
    want = np.array([quaternion_yaw(Quaternion(q)) for q in quaternions])
    assert np.array_equal(our_module.quaternion_yaws(quaternions), want)
    coordinates = rng.normal(size=(7, 2)) * 100
    for q in quaternions[::50]:
        translation = list(rng.normal(size=3) * 1000)
        for name in ("convert_global_coords_to_local", "convert_local_coords_to_global"):
            got = getattr(our_module, name)(coordinates, translation, list(q))
            assert np.array_equal(got, getattr(their_module, name)(coordinates, translation, list(q)))
    yaws = rng.uniform(-np.pi, np.pi, size=20)
    assert all(our_module.angle_of_rotation(y) == their_module.angle_of_rotation(y) for y in yaws)
    assert np.array_equal(our_module.angle_of_rotation(yaws), [their_module.angle_of_rotation(y) for y in yaws])
