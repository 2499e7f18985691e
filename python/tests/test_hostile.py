"""Hostile and careless input to the Python API: every writer refuses a
target that is not a regular file (a device, a FIFO, a socket, a folder)
and leaves it as it was; every integer argument is checked for type and
range with an error that begins with its name; `mbs.mono_views` names
the argument at fault for every array, map value, kind, scale and setting
it cannot take; every public function of ``mbs.torch`` checks what it is
given; non-finite disparities are invalid pixels of the loss and never
reach an index.
"""

from __future__ import annotations

import math
import os
import socket
import stat
import subprocess
from collections.abc import Iterator
from pathlib import Path
from typing import Any, Callable

import numpy as np
import numpy.typing as npt
import pytest
import torch

import mbs
from mbs.torch import (
    MultiBaselineDataset,
    S3Loss,
    augment_batch,
    augment_pair,
    cosine_momentum,
    ema_update_,
    geometry_weight,
    mirror_left,
    photometric_map,
    predict,
    sequence_weights,
    ssim,
    warp_to_reference,
)

MBS_TOOL = os.environ.get("MBS_TOOL", "target/debug/mbs-tool")
IMAGE = np.zeros((8, 8, 3), np.uint8)
MAP = np.ones((4, 4), np.float32)
# A map of IMAGE's size that every kind can hold: 1 to 2.
DEPTH: npt.NDArray[np.float32] = (1 + np.arange(64).reshape(8, 8) / 64).astype(np.float32)


@pytest.fixture
def special_files(tmp_path: Path) -> Iterator[list[tuple[str, str]]]:
    """A character device, a FIFO, a socket and a folder in the test's own
    folder, with the words a refusal names their kinds by. The device is
    a copy of /dev/null made with mknod (as root); a user who may not make
    devices gets /dev/null itself, which such a user cannot replace."""
    device: str | Path = tmp_path / "device"
    try:
        os.mknod(device, stat.S_IFCHR | 0o666, os.makedev(1, 3))
    except PermissionError:
        device = "/dev/null"
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    sock = socket.socket(socket.AF_UNIX)
    sock.bind(str(tmp_path / "socket"))
    (tmp_path / "folder").mkdir()
    yield [
        (str(device), "a character device"),
        (str(fifo), "a FIFO"),
        (str(tmp_path / "socket"), "a socket"),
        (str(tmp_path / "folder"), "a folder"),
    ]
    sock.close()


def identity(path: str | Path) -> tuple[int, int, int]:
    """Type, inode and device numbers: unchanged when a file is untouched."""
    info = os.lstat(path)
    return stat.S_IFMT(info.st_mode), info.st_ino, info.st_rdev


WRITERS = [
    ("write_rgb", lambda path: mbs.write_rgb(path, IMAGE)),
    ("write_pfm", lambda path: mbs.write_pfm(path, MAP)),
    ("write_kitti_disparity", lambda path: mbs.write_kitti_disparity(path, MAP)),
    ("write_exr", lambda path: mbs.write_exr(path, MAP)),
]


@pytest.mark.parametrize("name, write", WRITERS)
def test_writers_refuse_special_files_and_leave_them_untouched(
    special_files: list[tuple[str, str]], name: str, write: Callable[[str], None]
) -> None:
    for path, kind in special_files:
        before = identity(path)
        with pytest.raises(OSError) as error:
            write(path)
        message = str(error.value)
        assert path in message and kind in message and "not a regular file" in message, (name, message)
        assert identity(path) == before, (name, path)
    folder = special_files[3][0]
    assert os.listdir(folder) == []
    assert not [f for f in os.listdir(os.path.dirname(folder)) if f.endswith(".partial")]


def test_a_link_to_a_device_is_refused_and_a_link_to_nothing_replaced(
    special_files: list[tuple[str, str]], tmp_path: Path
) -> None:
    device = special_files[0][0]
    link = tmp_path / "link.png"
    link.symlink_to(device)
    with pytest.raises(OSError, match="a character device, not a regular file"):
        mbs.write_rgb(link, IMAGE)
    assert link.is_symlink() and os.readlink(link) == device
    dangling = tmp_path / "dangling.pfm"
    dangling.symlink_to(tmp_path / "gone.pfm")
    mbs.write_pfm(dangling, MAP)
    np.testing.assert_array_equal(mbs.read_pfm(dangling), MAP)


@pytest.mark.parametrize(
    "call, argument, error",
    [
        (lambda: mbs.match_stereo(IMAGE, IMAGE, max_disparity=-1), "max_disparity", ValueError),
        (lambda: mbs.match_stereo(IMAGE, IMAGE, max_disparity=2**70), "max_disparity", ValueError),
        (lambda: mbs.match_stereo(IMAGE, IMAGE, max_disparity=2**200), "max_disparity", ValueError),
        (lambda: mbs.match_stereo(IMAGE, IMAGE, max_disparity=16.5), "max_disparity", TypeError),  # type: ignore[arg-type]
        (lambda: mbs.match_stereo(IMAGE, IMAGE, max_disparity="64"), "max_disparity", TypeError),  # type: ignore[arg-type]
        (lambda: mbs.match_stereo(IMAGE, IMAGE, paths=-5), "paths", ValueError),
        (lambda: mbs.match_stereo(IMAGE, IMAGE, paths=True), "paths", TypeError),
        (lambda: mbs.extrapolate(IMAGE, IMAGE, dilate_radius=-1), "dilate_radius", ValueError),
        (lambda: mbs.extrapolate(IMAGE, IMAGE, dilate_radius=10**6), "dilate_radius", ValueError),
        (lambda: mbs.extrapolate(IMAGE, IMAGE, max_disparity=-3), "max_disparity", ValueError),
        (lambda: mbs.synth_scene(seed=-1), "seed", ValueError),
        (lambda: mbs.synth_scene(seed=2**64), "seed", ValueError),
        (lambda: mbs.synth_scene(seed=1.0), "seed", TypeError),  # type: ignore[arg-type]
        (lambda: mbs.synth_scene(views=-2), "views", ValueError),
        (lambda: mbs.synth_scene(width=-8), "width", ValueError),
        (lambda: mbs.synth_scene(height=None), "height", TypeError),  # type: ignore[arg-type]
        (lambda: mbs.synth_scene(supersample=2**40), "supersample", ValueError),
        (lambda: mbs.mono_views(IMAGE, DEPTH, "disparity", views=1), "views", ValueError),
        (lambda: mbs.mono_views(IMAGE, DEPTH, "disparity", views=2**70), "views", ValueError),
        (lambda: mbs.mono_views(IMAGE, DEPTH, "disparity", views=4.0), "views", TypeError),  # type: ignore[arg-type]
        (lambda: mbs.mono_views(IMAGE, DEPTH, "disparity", views=4, reference=4), "reference", ValueError),
        (lambda: mbs.mono_views(IMAGE, DEPTH, "disparity", reference=-1), "reference", ValueError),
        (lambda: mbs.mono_views(IMAGE, DEPTH, "disparity", reference=True), "reference", TypeError),
        (lambda: mbs.mono_views(IMAGE, DEPTH, "disparity", seed=-1), "seed", ValueError),
        (lambda: mbs.mono_views(IMAGE, DEPTH, "disparity", seed=2**64), "seed", ValueError),
        (lambda: mbs.mono_views(IMAGE, DEPTH, "disparity", seed=0.5), "seed", TypeError),  # type: ignore[arg-type]
        (lambda: mbs.mono_views(IMAGE, DEPTH, "disparity", dilate_radius=-1), "dilate_radius", ValueError),
    ],
)
def test_integer_arguments_are_checked_with_their_names(
    call: Callable[[], object], argument: str, error: type[Exception]
) -> None:
    with pytest.raises(error) as raised:
        call()
    assert type(raised.value) is error, repr(raised.value)
    assert str(raised.value).startswith(f"{argument}: "), str(raised.value)


def with_value(value: float, at: tuple[int, int] = (3, 5), base: npt.NDArray[np.float32] = DEPTH) -> Any:
    """``base`` with one value changed."""
    out = base.copy()
    out[at] = value
    return out


@pytest.mark.parametrize(
    "arguments, kwargs, message",
    [
        ((IMAGE.astype(np.float32), DEPTH, "disparity"), {}, "image: expected a uint8 HxWx3 RGB array"),
        ((IMAGE[:0], DEPTH, "disparity"), {}, "image: 0x8 pixels"),
        ((IMAGE, DEPTH.astype(np.float64), "disparity"), {}, "depth: expected a float32 HxW array"),
        ((IMAGE, DEPTH[None], "disparity"), {}, "depth: expected a float32 HxW array"),
        ((IMAGE, DEPTH[:, :7], "disparity"), {}, "depth: 8x7 pixels, but image is 8x8"),
        ((IMAGE, DEPTH, "metric"), {}, 'kind: unknown depth kind "metric": expected metric-depth'),
        ((IMAGE, DEPTH, "disparity"), {"scale": "linear"}, 'scale: "linear" is not as-is, metric or range'),
        (
            (IMAGE, DEPTH, "metric-depth"),
            {"scale": "as-is"},
            "scale: depth map: the as-is scaling cannot take a map of kind metric-depth",
        ),
        (
            (IMAGE, DEPTH, "inverse-relative"),
            {"scale": "metric", "focal": 500.0, "baseline": 0.1},
            "scale: depth map: the metric scaling cannot take a map of kind inverse-relative",
        ),
        ((IMAGE, DEPTH, "metric-depth"), {"scale": "metric"}, "focal: the metric scale needs focal and baseline"),
        ((IMAGE, DEPTH, "metric-depth"), {"scale": "metric", "focal": 500.0}, "baseline: the metric scale needs"),
        (
            (IMAGE, DEPTH, "metric-depth"),
            {"scale": "metric", "focal": 500.0, "baseline": 0.0},
            "baseline: 0 is not a positive number",
        ),
        (
            (IMAGE, DEPTH, "metric-depth"),
            {"scale": "metric", "focal": math.inf, "baseline": 0.1},
            "focal: inf is not a positive number",
        ),
        ((IMAGE, DEPTH, "metric-depth"), {"focal": 500.0}, "focal: only the metric scale takes focal and baseline"),
        ((IMAGE, DEPTH, "disparity"), {"baseline": 0.1}, "baseline: only the metric scale takes"),
        ((IMAGE, DEPTH, "metric-depth"), {"max_disparity": (0.2, 0.1)}, r"max_disparity: \(0.2, 0.1\): expected"),
        ((IMAGE, DEPTH, "metric-depth"), {"max_disparity": (0.0, 0.1)}, "max_disparity: "),
        ((IMAGE, DEPTH, "metric-depth"), {"max_disparity": (0.1, 1.5)}, "max_disparity: "),
        ((IMAGE, DEPTH, "metric-depth"), {"max_disparity": (0.1, 1.0)}, "max_disparity: "),
        ((IMAGE, DEPTH, "metric-depth"), {"max_disparity": (math.nan, 0.1)}, "max_disparity: "),
        ((IMAGE, DEPTH, "metric-depth"), {"max_disparity": (0.1,)}, r"max_disparity: expected \(low, high\), got 1"),
        ((IMAGE, with_value(math.nan), "inverse-relative"), {}, "depth: 1 of 64 values are NaN or infinite"),
        ((IMAGE, with_value(math.inf), "metric-depth"), {}, "depth: 1 of 64 values are NaN or infinite"),
        ((IMAGE, with_value(math.nan), "disparity"), {}, "depth: 1 NaN or negative disparities"),
        ((IMAGE, np.full((8, 8), np.inf, np.float32), "disparity"), {}, "depth: no valid disparity at all"),
        (
            (IMAGE, with_value(0.0), "metric-depth"),
            {},
            "depth: 1 of 64 values are a zero or negative depth for a map of kind metric-depth: "
            "a relative model\\? its kind is inverse-relative",
        ),
        ((IMAGE, with_value(-1.0), "disparity"), {}, "depth: 1 NaN or negative disparities"),
        ((IMAGE, np.ones((8, 8), np.float32), "inverse-relative"), {}, "depth: every value is 1: a constant map"),
        ((IMAGE, DEPTH * 100, "disparity"), {}, "depth: image_1: every pixel is masked"),
        ((IMAGE, DEPTH, "disparity"), {"dilation": "disc"}, "dilation: "),
        ((IMAGE, DEPTH, "disparity"), {"inpaint": "lama"}, "inpaint: "),
    ],
)
def test_mono_views_names_what_it_cannot_take(
    arguments: tuple[Any, Any, Any], kwargs: dict[str, Any], message: str
) -> None:
    with pytest.raises(ValueError, match=f"^{message}"):
        mbs.mono_views(*arguments, **kwargs)


def test_numpy_integers_are_integers() -> None:
    depth = mbs.match_stereo(IMAGE, IMAGE, max_disparity=np.int64(16), paths=np.uint8(5))
    assert depth.shape == (8, 8)
    assert mbs.synth_scene(seed=np.uint64(3), views=np.int32(2), width=16, height=8)["views"][0].shape == (8, 16, 3)


@pytest.fixture(scope="module")
def manifest(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("synth")
    done = subprocess.run(
        [
            MBS_TOOL,
            "synth",
            "--out",
            str(root),
            "--weathers",
            "ClearNoon",
            "--no-checksums",
            "--seed",
            "2",
            "--frames",
            "1",
            "--towns",
            "Town01",
            "--width",
            "64",
            "--height",
            "32",
            "--focal",
            "32",
        ],
        capture_output=True,
        text=True,
    )
    assert done.returncode == 0, done.stdout + done.stderr
    return root / "manifest.json"


@pytest.mark.parametrize(
    "kwargs, argument, error",
    [
        ({"batch_size": 1.5}, "batch_size", TypeError),
        ({"batch_size": -1}, "batch_size", ValueError),
        ({"batch_size": 2**80}, "batch_size", ValueError),
        ({"seed": -1}, "seed", ValueError),
        ({"seed": 0.5}, "seed", TypeError),
        ({"crop": (-16, 32)}, "crop height", ValueError),
        ({"crop": (16, 2**70)}, "crop width", ValueError),
        ({"crop": (16.5, 32)}, "crop height", TypeError),
        ({"crop": (16, 32, 3)}, "crop", ValueError),
        ({"steps": True}, "steps", TypeError),
        ({"steps": 2.0}, "steps", TypeError),
        ({"augment": {"bogus": 1}}, "augment", ValueError),
        ({"augment": {"occlusion_max_rects": -1}}, "augment", ValueError),
        ({"augment": ["brightness"]}, "augment", ValueError),
    ],
)
def test_the_dataset_checks_its_arguments(
    manifest: Path, kwargs: dict[str, Any], argument: str, error: type[Exception]
) -> None:
    settings = {"steps": 1, "batch_size": 1, "crop": (16, 32), **kwargs}
    with pytest.raises(error) as raised:
        MultiBaselineDataset(manifest, **settings)
    assert type(raised.value) is error, repr(raised.value)
    assert str(raised.value).startswith(f"{argument}: "), str(raised.value)
    if kwargs.get("augment") == {"bogus": 1}:
        assert "'bogus'" in str(raised.value) or '"bogus"' in str(raised.value)


def test_a_dataset_step_must_be_an_integer(manifest: Path) -> None:
    data = MultiBaselineDataset(manifest, steps=2, batch_size=1, crop=(16, 32))
    with pytest.raises(TypeError, match="^step: "):
        data[0.5]  # type: ignore[index]
    assert data[np.int64(1)]["step"] == 1


def loss_inputs(batch: int = 2, height: int = 8, width: int = 16) -> dict[str, Any]:
    torch.manual_seed(0)
    image = torch.rand(batch, 3, height, width)
    return dict(
        reference=image,
        student_target=torch.rand(batch, 3, height, width),
        teacher_target=torch.rand(batch, 3, height, width),
        student_disparity=(torch.rand(batch, 1, height, width) * 4).requires_grad_(True),
        teacher_disparity=torch.rand(batch, 1, height, width) * 4,
        student_sides=["right", "left"][:batch],
        teacher_sides=["right", "left"][:batch],
        ratios=[0.5, 0.5][:batch],
    )


@pytest.mark.parametrize("which", ["student_disparity", "teacher_disparity"])
@pytest.mark.parametrize("value", [math.nan, math.inf, -math.inf])
def test_non_finite_disparities_are_invalid_pixels(which: str, value: float) -> None:
    """The pixels carry no weight and no gradient; the rest of the loss is
    finite and the same as with those pixels' weights zeroed by hand."""
    inputs = loss_inputs()
    poisoned = inputs[which].detach().clone()
    poisoned[0, 0, 3, 5] = value
    poisoned[1, 0, :, 0] = value
    inputs[which] = poisoned.requires_grad_(which == "student_disparity")
    out = S3Loss(view_weight=0.1)(**inputs)
    assert torch.isfinite(out.total), out
    if which == "student_disparity":
        out.total.backward()
        grad = inputs[which].grad
        assert torch.isfinite(grad).all()
        assert grad[0, 0, 3, 5] == 0 and (grad[1, 0, :, 0] == 0).all()
        assert out.student_non_finite.item() == 1 + 8
        assert out.student_mask[0, 0, 3, 5] == 0 and out.weight_map[0, 0, 3, 5] == 0
    else:
        assert out.student_non_finite.item() == 0
        assert out.teacher_mask[0, 0, 3, 5] == 0 and (out.teacher_mask[1, 0, :, 0] == 0).all()


def test_warp_never_indexes_with_a_non_finite_disparity() -> None:
    target = torch.arange(2 * 3 * 4 * 6, dtype=torch.float32).view(2, 3, 4, 6)
    disparity = torch.full((2, 1, 4, 6), math.nan)
    disparity[1] = math.inf
    signs = torch.tensor([1.0, 1.0]).view(2, 1, 1, 1)
    warped = warp_to_reference(target, disparity, signs)
    torch.testing.assert_close(warped[0], target[0, :, :, :1].expand(3, 4, 6))
    torch.testing.assert_close(warped[1], target[1, :, :, :1].expand(3, 4, 6))


def test_every_mbs_torch_function_names_a_bad_argument() -> None:
    images = torch.rand(2, 3, 8, 16)
    draws = (torch.ones(2), torch.ones(2), torch.ones(2), torch.zeros(2, 1, 8, 16))
    network = lambda left, right: left[:, :1]  # noqa: E731
    module = torch.nn.Linear(2, 2)
    cases: list[tuple[Callable[[], object], str, type[Exception]]] = [
        (lambda: predict(network, images, images, ["up", "right"]), "sides", ValueError),
        (lambda: predict(network, images, images, "rightleft"), "sides", TypeError),
        (lambda: predict(network, images, images[:, :, :4], ["right", "left"]), "target", ValueError),
        (lambda: predict(network, images, images, ["right"]), "sides", ValueError),
        (lambda: predict(lambda lt, rt: lt[:, :1, :4], images, images, ["right", "left"]), "network", ValueError),
        (lambda: predict("net", images, images, ["right", "left"]), "network", ValueError),  # type: ignore[arg-type]
        (lambda: mirror_left(images, ["left"]), "sides", ValueError),
        (lambda: mirror_left(images, ["left", "down"]), "sides", ValueError),
        (lambda: mirror_left([1, 2], ["left", "left"]), "tensor", TypeError),  # type: ignore[arg-type]
        (lambda: ssim(images, images, 0), "window", ValueError),
        (lambda: ssim(images, images, 4), "window", ValueError),
        (lambda: ssim(images, images, 17), "window", ValueError),
        (lambda: ssim(images, images[:1], 3), "y", ValueError),
        (lambda: ssim(images[0], images[0], 3), "x", ValueError),
        (lambda: photometric_map(images, images, 1.5, 3), "alpha", ValueError),
        (lambda: photometric_map(images, images, math.nan, 3), "alpha", ValueError),
        (lambda: augment_pair(images[0], images[0], *draws), "reference", ValueError),
        (lambda: augment_pair(images[:0], images[:0], *draws), "reference", ValueError),
        (lambda: augment_pair(images, images[:, :, :4], *draws), "target", ValueError),
        (lambda: augment_pair(images, images, torch.ones(3), *draws[1:]), "brightness", ValueError),
        (
            lambda: augment_pair(images, images, draws[0], torch.tensor([1.0, math.nan]), *draws[2:]),
            "contrast",
            ValueError,
        ),
        (lambda: augment_pair(images, images, *draws[:3], torch.zeros(2, 1, 8, 8)), "occlusion", ValueError),
        (lambda: augment_batch({"reference": images}), "batch", ValueError),
        (lambda: augment_batch([images]), "batch", ValueError),  # type: ignore[arg-type]
        (lambda: warp_to_reference(images, torch.zeros(2, 1, 8, 15), torch.ones(2, 1, 1, 1)), "disparity", ValueError),
        (lambda: warp_to_reference(images, torch.zeros(2, 1, 8, 16), torch.ones(2)), "signs", ValueError),
        (lambda: cosine_momentum(0, 0), "total_steps", ValueError),
        (lambda: cosine_momentum(-1, 10), "step", ValueError),
        (lambda: cosine_momentum(1.5, 10), "step", TypeError),  # type: ignore[arg-type]
        (lambda: cosine_momentum(0, 10, base=math.nan), "base", ValueError),
        (lambda: geometry_weight(0, 0), "total_steps", ValueError),
        (lambda: geometry_weight(-1, 10), "step", ValueError),
        (lambda: geometry_weight(0, 10, start=math.nan), "start", ValueError),
        (lambda: sequence_weights(-1), "n", ValueError),
        (lambda: sequence_weights(0), "n", ValueError),
        (lambda: sequence_weights(3, gamma=math.inf), "gamma", ValueError),
        (lambda: sequence_weights(3.0), "n", TypeError),  # type: ignore[arg-type]
        (lambda: ema_update_(module, module, math.nan), "momentum", ValueError),
        (lambda: ema_update_("teacher", module, 0.5), "teacher", ValueError),  # type: ignore[arg-type]
        (lambda: S3Loss(tau=math.nan), "tau", ValueError),
        (lambda: S3Loss(omega=math.inf), "omega", ValueError),
        (lambda: S3Loss(ssim_window=3.0), "ssim_window", TypeError),  # type: ignore[arg-type]
        (lambda: S3Loss(geometry="yes"), "geometry", TypeError),  # type: ignore[arg-type]
        (lambda: S3Loss(outside_mask_weight=-0.1), "outside_mask_weight", ValueError),
    ]
    for call, argument, error in cases:
        with pytest.raises(error) as raised:
            call()
        assert type(raised.value) is error, (argument, repr(raised.value))
        assert str(raised.value).startswith(f"{argument}: "), (argument, str(raised.value))


def test_the_loss_refuses_empty_batches_bad_ratios_and_other_devices() -> None:
    loss = S3Loss()
    cases = [
        ({**loss_inputs(), "ratios": [0.5, 0.0]}, "ratios"),
        ({**loss_inputs(), "ratios": [0.5, math.nan]}, "ratios"),
        ({**loss_inputs(), "ratios": [0.5, -1.0]}, "ratios"),
        ({**loss_inputs(), "ratios": ["a", "b"]}, "ratios"),
        ({**loss_inputs(), "student_sides": ["right", "up"]}, "student_sides"),
        ({**loss_inputs(), "teacher_disparity": torch.rand(2, 1, 8, 15)}, "teacher_disparity"),
        ({**loss_inputs(), "geometry_weight": math.nan}, "geometry_weight"),
    ]
    empty = {
        name: value[:0] if isinstance(value, (torch.Tensor, list)) else value for name, value in loss_inputs().items()
    }
    cases.append((empty, "reference"))
    # A tensor on another device: the meta device stands for a GPU here.
    cases.append(({**loss_inputs(), "teacher_target": torch.rand(2, 3, 8, 16, device="meta")}, "teacher_target"))
    for inputs, argument in cases:
        with pytest.raises(ValueError) as raised:
            loss(**inputs)
        assert str(raised.value).startswith(f"{argument}: "), (argument, str(raised.value))
