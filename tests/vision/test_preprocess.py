import cv2
import numpy as np
import pytest

from app.vision.histogram import grey_histogram, grey_stats, render_histogram
from app.vision.preprocess import Denoise, Downscale, Enhance, to_gray

# A worked example in the paper's style: the 3x3 neighbourhood of the centre pixel.
NEIGHBOURHOOD = np.array([[10, 2, 3], [4, 5, 6], [7, 8, 1]], np.uint8)


def test_median_of_worked_example_is_five():
    assert Denoise("median", 3)(NEIGHBOURHOOD)[1, 1] == 5


def test_mean_filter_of_worked_example_is_rounded_average():
    assert Denoise("mean", 3)(NEIGHBOURHOOD)[1, 1] == round(NEIGHBOURHOOD.sum() / 9)


def test_median_removes_salt_noise_that_mean_only_spreads():
    image = np.full((9, 9), 100, np.uint8)
    image[4, 4] = 255
    assert Denoise("median", 3)(image)[4, 4] == 100
    assert Denoise("mean", 3)(image)[4, 4] > 100


@pytest.mark.parametrize("method", ["median", "mean", "gaussian"])
def test_every_filter_keeps_a_flat_image_flat(method):
    image = np.full((20, 20), 77, np.uint8)
    for kernel in (1, 3, 5, 7):
        assert np.array_equal(Denoise(method, kernel)(image), image)


@pytest.mark.parametrize(
    "shape", [(1, 1), (1, 9), (9, 1), (2, 2), (2, 7), (7, 2), (3, 3), (31, 17), (240, 320)]
)
def test_the_default_gaussian_is_opencvs_to_the_grey_level(shape):
    # The 3x3 Gaussian runs compiled (a live camera's every frame); it must give what
    # OpenCV gives, edges included, on noise (every rounding case) and on a view.
    rng = np.random.default_rng(sum(shape))
    image = rng.integers(0, 256, shape, dtype=np.uint8)
    assert np.array_equal(Denoise("gaussian", 3)(image), cv2.GaussianBlur(image, (3, 3), 0))
    view = np.repeat(image, 2, axis=1)[:, ::2]
    assert np.array_equal(Denoise("gaussian", 3)(view), cv2.GaussianBlur(image, (3, 3), 0))


def test_kernel_outside_paper_range_is_refused():
    with pytest.raises(ValueError, match="kernel"):
        Denoise("median", 9)
    with pytest.raises(ValueError, match="unknown"):
        Denoise("bilateral", 3)  # type: ignore[arg-type]


def test_grayscale_uses_luma_weights():
    red = np.zeros((2, 2, 3), np.uint8)
    red[..., 2] = 255
    assert to_gray(red)[0, 0] == 76  # 0.299 * 255


def test_histogram_counts_every_pixel_and_stats_match_numpy():
    rng = np.random.default_rng(1)
    gray = rng.integers(0, 256, (48, 64), dtype=np.uint8)
    hist = grey_histogram(gray)
    assert hist.shape == (256,) and hist.sum() == gray.size
    assert hist[17] == np.count_nonzero(gray == 17)
    stats = grey_stats(gray)
    assert stats.mean == pytest.approx(gray.mean())
    assert stats.std == pytest.approx(gray.std())


def test_histogram_picture_has_requested_size():
    gray = np.full((10, 10), 200, np.uint8)
    picture = render_histogram(grey_histogram(gray), grey_stats(gray), 256, 120)
    assert picture.shape == (120, 256, 3)


def test_equalisation_stretches_a_dark_low_contrast_frame():
    dark = (np.arange(100, dtype=np.uint8).reshape(10, 10) // 5) + 10  # levels 10..29
    enhanced = Enhance("equalize")(dark)
    assert int(enhanced.max()) - int(enhanced.min()) > 200
    assert np.array_equal(Enhance("none")(dark), dark)


def test_downscale_keeps_aspect_and_reports_scale():
    frame = np.zeros((480, 640), np.uint8)
    small = Downscale(320)(frame)
    assert small.shape == (240, 320)
    assert Downscale(320).scale_for(640) == 2.0
    assert Downscale(320).scale_for(200) == 1.0
    assert Downscale(0)(frame) is frame


def test_gaussian_reduces_noise_variance():
    rng = np.random.default_rng(2)
    noisy = np.clip(rng.normal(128, 10, (100, 100)), 0, 255).astype(np.uint8)
    assert Denoise("gaussian", 5)(noisy).std() < noisy.std() / 2
    assert cv2.meanStdDev(noisy)[1][0, 0] > 9
