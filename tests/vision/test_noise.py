import numpy as np
import pytest

from app.vision.noise import NoiseEstimator, noise_sigma


@pytest.mark.parametrize("sigma", [2.0, 5.0, 12.0])
def test_noise_sigma_recovers_gaussian_sigma(sigma):
    rng = np.random.default_rng(3)
    difference = np.abs(rng.normal(0, sigma, (240, 320))).round().clip(0, 255).astype(np.uint8)
    assert noise_sigma(difference) == pytest.approx(sigma, rel=0.1)


def test_noise_estimate_ignores_a_moving_object():
    rng = np.random.default_rng(4)
    difference = np.abs(rng.normal(0, 3, (240, 320))).round().astype(np.uint8)
    difference[50:150, 50:150] = 120  # an object covering 13% of the frame
    assert noise_sigma(difference) == pytest.approx(3.0, rel=0.2)


def test_threshold_follows_noise_within_floor_and_ceiling():
    quiet, noisy = NoiseEstimator(), NoiseEstimator()
    rng = np.random.default_rng(5)
    daylight = np.full((60, 80), 120, np.uint8)
    for _ in range(20):
        quiet.update(np.zeros((60, 80), np.uint8), daylight)
        noisy.update(np.abs(rng.normal(0, 8, (60, 80))).astype(np.uint8), daylight)
    assert quiet.threshold == quiet.floor
    assert noisy.threshold > 25
    assert noisy.threshold <= noisy.ceiling


@pytest.mark.parametrize(("mean_grey", "floor"), [(120, 10.0), (64, 10.0), (48, 7.5), (10, 5.0)])
def test_the_floor_comes_down_with_the_light_in_a_dark_scene(mean_grey, floor):
    clean = NoiseEstimator()
    for _ in range(40):
        clean.update(np.zeros((60, 80), np.uint8), np.full((60, 80), mean_grey, np.uint8))
    assert clean.threshold == pytest.approx(floor, abs=0.05)


def test_noise_is_measured_on_still_pixels_when_told_what_moves():
    rng = np.random.default_rng(6)
    difference = np.abs(rng.normal(0, 3, (240, 320))).round().astype(np.uint8)
    moving = np.zeros_like(difference)
    moving[:, :200] = 255  # an object covering 62% of the frame
    difference[:, :200] = 90
    assert noise_sigma(difference) > 100  # The median is the object's.
    assert noise_sigma(difference, moving) == pytest.approx(3.0, rel=0.2)
    moving[:] = 255
    assert noise_sigma(difference, moving) is None  # Nothing still to tell by.
