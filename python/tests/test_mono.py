"""`mbs.mono_views` on real data: the views of a virtual rig from one image
and a depth or disparity map a caller's own network gave (issue 60), on
Middlebury's Tsukuba row 3 (five cameras one baseline apart, the middle
one's true disparity).

Each synthesised camera is, byte for byte, what `mbs.extrapolate` makes
from the same image with that camera's disparity (both call the library's
one `synthesize`, and fill a disparity's unknown pixels alike); the synthesised neighbours are closer to the real ones
than the image itself is; the range scaling's largest disparity is the
drawn fraction of the width, the same for the same seed and id and another
for another id; the metric scaling is exactly f B / Z.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import numpy.typing as npt
import pytest

import mbs

TSUKUBA = Path(__file__).resolve().parents[2] / "testdata" / "middlebury-tsukuba-row3"
# The ground truth's unknown border (0 in the file), pixels on each side.
BORDER = 18


def column(k: int) -> npt.NDArray[np.uint8]:
    """Camera ``k`` (1 to 5) of the row."""
    return mbs.read_rgb(TSUKUBA / f"scene1.row3.col{k}.ppm")


@pytest.fixture(scope="module")
def truth() -> npt.NDArray[np.float32]:
    """Column 3's true disparity against its neighbours (the file's value /
    16), ``inf`` where unknown (0 in the file: an 18 px border)."""
    values = mbs.read_rgb(TSUKUBA / "truedisp.row3.col3.pgm")[..., 0].astype(np.float32) / 16
    inner = values[BORDER:-BORDER, BORDER:-BORDER]
    assert inner.min() > 0 and (values == 0).sum() == values.size - inner.size, "only the border is unknown"
    return np.where(values > 0, values, np.float32(np.inf))


@pytest.fixture(scope="module")
def disparity(truth: npt.NDArray[np.float32]) -> npt.NDArray[np.float32]:
    """The true disparity with its unknown border filled from the nearest
    known pixel: what the fill from the background side makes of it."""
    return np.pad(truth[BORDER:-BORDER, BORDER:-BORDER], BORDER, mode="edge")


def psnr(a: npt.NDArray[np.uint8], b: npt.NDArray[np.uint8]) -> float:
    error = np.mean((a.astype(np.float64) - b.astype(np.float64)) ** 2)
    return float(10 * np.log10(255.0**2 / error))


def test_each_camera_is_extrapolate_at_its_baselines(
    truth: npt.NDArray[np.float32], disparity: npt.NDArray[np.float32]
) -> None:
    """With ``inf`` where unknown, as the library, ``mbs.extrapolate`` and
    ``mbs-tool mono`` take a disparity: filled from the background side."""
    image = column(3)
    rig = mbs.mono_views(image, truth, "disparity", views=5, reference=2)
    assert len(rig["views"]) == len(rig["masks"]) == 5
    np.testing.assert_array_equal(rig["views"][2], image)
    assert rig["masks"][2] is None
    np.testing.assert_array_equal(rig["disparity"], disparity)
    assert rig["drawn_fraction"] is None
    for steps in (1, 2):
        scaled = truth * np.float32(steps)
        pair = mbs.extrapolate(image, image, disparity_left=scaled, disparity_right=scaled)
        np.testing.assert_array_equal(pair["disparity_2"], disparity * np.float32(steps))
        for k, view, mask in (
            (2 - steps, pair["image_1"], pair["mask_1"]),
            (2 + steps, pair["image_4"], pair["mask_4"]),
        ):
            assert rig["views"][k].dtype == np.uint8 and rig["views"][k].shape == image.shape
            np.testing.assert_array_equal(rig["views"][k], view, err_msg=f"camera {k}")
            np.testing.assert_array_equal(rig["masks"][k], mask, err_msg=f"camera {k}")
    for k in (0, 1, 3, 4):
        synthesised = rig["masks"][k]
        assert synthesised is not None and set(np.unique(synthesised)) == {0, 255}, f"camera {k}"
    filled = mbs.mono_views(image, disparity, "disparity", views=5, reference=2)
    for ours, theirs in zip(rig["views"] + rig["masks"], filled["views"] + filled["masks"]):
        np.testing.assert_array_equal(ours, theirs)


# PSNR (dB) of each synthesised camera (0 to 4: columns 1 to 5) against the
# real one, measured with the true disparity and the default dilation and
# inpainting; the floors are these less 0.3 dB. Column 3 itself scores 14.46,
# 16.65, 16.70 and 14.44 dB against them: the warp gains 12 to 14 dB.
MEASURED = {0: 26.88, 1: 30.34, 3: 30.01, 4: 26.19}


def test_synthesised_cameras_are_close_to_the_real_ones(truth: npt.NDArray[np.float32]) -> None:
    image = column(3)
    rig = mbs.mono_views(image, truth, "disparity", views=5, reference=2)
    for k, measured in MEASURED.items():
        real = column(k + 1)
        ours, unwarped = psnr(rig["views"][k], real), psnr(image, real)
        print(f"camera {k}: {ours:.2f} dB synthesised, {unwarped:.2f} dB the image itself")
        assert ours >= measured - 0.3, (k, ours)
        assert ours > unwarped + 10, (k, ours, unwarped)


def test_the_range_scaling_draws_the_largest_disparity_per_image(disparity: npt.NDArray[np.float32]) -> None:
    image = column(3)
    width = image.shape[1]
    rig = mbs.mono_views(image, disparity, "inverse-relative", seed=7, sample_id="tsukuba")
    fraction = rig["drawn_fraction"]
    assert fraction is not None and 0.05 <= fraction <= 0.15
    largest = float(rig["disparity"].max())
    assert abs(largest - fraction * width) <= 1e-4 * fraction * width, (largest, fraction)
    # A non-negative map is only scaled: the ratios of inverse depth stay.
    np.testing.assert_allclose(rig["disparity"], disparity * (largest / disparity.max()), rtol=1e-5)
    again = mbs.mono_views(image, disparity, "inverse-relative", seed=7, sample_id="tsukuba")
    assert again["drawn_fraction"] == fraction
    np.testing.assert_array_equal(again["disparity"], rig["disparity"])
    for ours, theirs in zip(rig["views"] + rig["masks"], again["views"] + again["masks"]):
        np.testing.assert_array_equal(ours, theirs)
    others = [mbs.mono_views(image, disparity, "inverse-relative", seed=7, sample_id=i) for i in ("a", "b")]
    other_seed = mbs.mono_views(image, disparity, "inverse-relative", seed=8, sample_id="tsukuba")
    fractions = {fraction, other_seed["drawn_fraction"]} | {other["drawn_fraction"] for other in others}
    assert len(fractions) == 4, fractions
    assert not np.array_equal(others[0]["disparity"], others[1]["disparity"])
    assert not np.array_equal(others[0]["views"][0], others[1]["views"][0])
    # A metric depth map is inverted first, then scaled the same way.
    depth = np.float32(1) / disparity
    metric = mbs.mono_views(image, depth, "metric-depth", seed=7, sample_id="tsukuba")
    assert metric["drawn_fraction"] == fraction
    np.testing.assert_allclose(metric["disparity"], rig["disparity"], rtol=1e-5)


def test_the_metric_scaling_is_focal_times_baseline_over_depth(disparity: npt.NDArray[np.float32]) -> None:
    image = column(3)
    depth = (np.float32(50) / (disparity + np.float32(1))).astype(np.float32)
    focal, baseline = 615.0, 0.16
    rig = mbs.mono_views(image, depth, "metric-depth", scale="metric", focal=focal, baseline=baseline)
    expected = (np.float64(focal) * np.float64(baseline) / depth.astype(np.float64)).astype(np.float32)
    np.testing.assert_array_equal(rig["disparity"], expected)
    assert rig["drawn_fraction"] is None
    assert len(rig["views"]) == 4 and rig["masks"][1] is None
    np.testing.assert_array_equal(rig["views"][1], image)
