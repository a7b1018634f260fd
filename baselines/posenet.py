"""``posenet``: absolute pose regression, one network trained per scene on its mapping frames.

PoseNet (Kendall et al. 2015) with the learned loss weighting of Kendall & Cipolla (2017), as
MS-Transformer trains it: ``L = l_x exp(-s_x) + s_x + l_q exp(-s_q) + s_q``, ``l_x`` the mean
Euclidean error of the (normalised) camera centre, ``l_q`` that of the unit quaternion, ``s_x`` and
``s_q`` learned from 0 and -3. Adam with weight decay and step decay, random crops and colour jitter
in training, the centre crop at test.

No pretrained ImageNet backbone can be installed here, so the backbone is the conv stack of the
project's own image encoder (:func:`baselines.global_descriptors.encoder_backbone`), fine-tuned;
``backbone: scratch`` trains the same layers from a random initialisation. Head: global average
pool, FC -> ReLU -> dropout, then FC 3 (centre) and FC 4 (quaternion).

The training budget is a fixed number of optimisation steps (not epochs, not seconds), so the map
is a function of the scene and the seed, and training time does not grow with the scene. The map
holds the weights and the translation normalisation. Masks are ignored (``uses_masks = False``);
a pose is always returned.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import torch
from scipy.spatial.transform import Rotation
from torch import nn
from torch.nn import functional as F

from baselines.global_descriptors import encoder_backbone, single_threaded
from openreloc_bench import config as cfglib
from openreloc_bench.bars import tqdm
from openreloc_bench.data import mapfile
from openreloc_bench.data.types import SceneSequence
from openreloc_bench.errors import DataError
from openreloc_bench.methods import PoseEstimate, QueryFrame
from openreloc_bench.vision.learned_segment import torch_threads
from openreloc_bench.vision.offline import ImageTower, TowerConfig, uint8_batch_to_tensor

MAP_FORMAT = "posenet-map"
MAP_VERSION = 1
BACKBONES = ("encoder", "scratch")
_WEIGHT_PREFIX = "net."
LOSS_TERMS = ("loss", "l_x", "l_q", "s_x", "s_q")


@dataclass
class PoseNetConfig:
    """Every setting of :class:`PoseNet`; all of them shape the map."""

    backbone: str = "encoder"
    """``encoder``: the committed image encoder's conv layers, fine-tuned; ``scratch``: the same
    layers randomly initialised."""
    input_width: int = 128
    """Network input width (pixels); frames are resized so that a crop of this size fits."""
    input_height: int = 96
    """Network input height."""
    crop_margin: float = 0.125
    """Frames are resized to (1 + margin) x the input size; training takes random crops of the input
    size, localization the centre crop (PoseNet's resize 256 / crop 224)."""
    hidden: int = 1024
    """Width of the head's fully connected layer."""
    dropout: float = 0.1
    """Dropout after it (training only)."""
    steps: int = 2000
    """Optimisation steps: the fixed training budget per scene."""
    batch_size: int = 8
    """Frames per step (the indoor recipe's batch)."""
    lr: float = 1e-3
    """Adam learning rate."""
    weight_decay: float = 1e-4
    """Adam weight decay."""
    lr_decay_at: list[float] = field(default_factory=lambda: [0.6, 0.85])
    """Fractions of ``steps`` after which the learning rate is divided by 10."""
    s_x: float = 0.0
    """Initial log-variance weight of the translation loss."""
    s_q: float = -3.0
    """Initial log-variance weight of the rotation loss (the indoor value)."""
    brightness: float = 0.5
    """Colour jitter: each training image is scaled by a factor in [1 - b, 1 + b]..."""
    contrast: float = 0.5
    """...blended with its mean grey by a factor in [1 - c, 1 + c]..."""
    saturation: float = 0.5
    """...and with its own grey image by a factor in [1 - s, 1 + s]."""
    seed: int = 0
    """Seeds the initialisation, batches, crops and jitter: on one device and thread count, the same
    scene and seed give the same weights."""
    threads: int = 2
    """Torch threads while training on the CPU."""
    device: str = "cpu"
    """``cpu`` or ``cuda`` (training and localization)."""

    def __post_init__(self) -> None:
        if self.backbone not in BACKBONES:
            raise ValueError(f"'backbone' must be one of {', '.join(BACKBONES)}, got {self.backbone!r}")
        if self.device not in ("cpu", "cuda"):
            raise ValueError(f"'device' must be 'cpu' or 'cuda', got {self.device!r}")
        if self.device == "cuda" and not torch.cuda.is_available():
            raise ValueError("'device' is 'cuda' but torch sees no CUDA device here")
        cfglib.check_ranges(
            self,
            at_least_one=("input_width", "input_height", "hidden", "steps", "batch_size", "threads"),
            positive=("lr",),
            non_negative=("crop_margin", "weight_decay"),
            share=("dropout", "lr_decay_at", "brightness", "contrast", "saturation"),
        )


def _network_config(cfg: Any) -> Any:
    """What a map must agree on with the method loading it: all but where it trained (a map trained
    on a GPU localizes on a CPU)."""
    return {k: v for k, v in cfg.items() if k not in ("device", "threads")} if isinstance(cfg, dict) else cfg


class PoseRegressor(nn.Module):
    """Backbone -> global average pool -> FC -> ReLU -> dropout -> (centre, quaternion)."""

    def __init__(self, cfg: PoseNetConfig, pretrained: bool):
        super().__init__()
        self.backbone = encoder_backbone() if pretrained else ImageTower(TowerConfig()).features
        width = TowerConfig().widths[-1]
        self.fc = nn.Sequential(nn.Linear(width, cfg.hidden), nn.ReLU(inplace=True), nn.Dropout(cfg.dropout))
        self.t = nn.Linear(cfg.hidden, 3)
        self.q = nn.Linear(cfg.hidden, 4)

    def forward(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        h = self.fc(self.backbone(x).mean(dim=(2, 3)))
        return self.t(h), F.normalize(self.q(h), dim=1)


def pose_targets(poses: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Camera centres (N, 3) and unit quaternions (N, 4, scipy's x, y, z, w) of camera-to-world
    poses, each quaternion on the w >= 0 hemisphere so that q and -q do not pull apart."""
    q = Rotation.from_matrix(poses[:, :3, :3]).as_quat()
    q *= np.where(q[:, 3:] < 0, -1.0, 1.0)
    return poses[:, :3, 3].astype(np.float32), q.astype(np.float32)


def jitter(x: torch.Tensor, cfg: PoseNetConfig, gen: torch.Generator) -> torch.Tensor:
    """Random brightness, contrast and saturation per image of a [0, 1] batch (N, 3, H, W)."""
    n = len(x)

    def factor(strength: float) -> torch.Tensor:
        return (1 + strength * (2 * torch.rand(n, 1, 1, 1, generator=gen) - 1)).to(x.device)

    x = x * factor(cfg.brightness)
    grey = (0.299 * x[:, 0] + 0.587 * x[:, 1] + 0.114 * x[:, 2])[:, None]
    x = grey.mean(dim=(2, 3), keepdim=True) + factor(cfg.contrast) * (x - grey.mean(dim=(2, 3), keepdim=True))
    grey = (0.299 * x[:, 0] + 0.587 * x[:, 1] + 0.114 * x[:, 2])[:, None]
    return (grey + factor(cfg.saturation) * (x - grey)).clamp_(0, 1)


class PoseNet:
    """A per-scene absolute pose regressor (see the module doc)."""

    name = "posenet"
    reference = "Kendall, Grimes and Cipolla, PoseNet, ICCV 2015, with the learned loss weights of Kendall and Cipolla, CVPR 2017"
    uses_masks = False
    """Query instance masks (oracle-mask track) are never read."""

    def __init__(self, **overrides: Any):
        self.config: PoseNetConfig = cfglib.from_dict(PoseNetConfig, overrides, "posenet")
        self._net: PoseRegressor | None = None
        self._t_mean = np.zeros(3, np.float32)
        self._t_scale = 1.0

    # ---------------------------------------------------------------------------------- images

    def _resized(self, rgb: np.ndarray) -> np.ndarray:
        """A frame at (1 + crop_margin) x the input size (uint8)."""
        c = self.config
        size = (round(c.input_width * (1 + c.crop_margin)), round(c.input_height * (1 + c.crop_margin)))
        return cv2.resize(rgb, size, interpolation=cv2.INTER_AREA)

    def _centre_crop(self, img: np.ndarray) -> np.ndarray:
        c = self.config
        y, x = (img.shape[0] - c.input_height) // 2, (img.shape[1] - c.input_width) // 2
        return img[y : y + c.input_height, x : x + c.input_width]

    # ---------------------------------------------------------------------------------- mapping

    def build_map(self, mapping: SceneSequence, map_dir: Path) -> None:
        c = self.config
        if len(mapping) < 2:
            raise DataError(Path(map_dir), f"posenet needs at least 2 mapping frames, got {len(mapping)}")
        images = np.stack([self._resized(f.color) for f in tqdm(mapping, desc="posenet frames", leave=False)])
        centres, quats = pose_targets(mapping.poses)
        t_mean = centres.mean(axis=0)
        t_scale = float(max(np.sqrt(((centres - t_mean) ** 2).sum(axis=1).mean()), 1e-3))
        cuda = [torch.cuda.current_device()] if c.device == "cuda" else []
        with torch_threads(c.threads), torch.random.fork_rng(devices=cuda):  # seeds without touching the caller's RNG
            net, final = self._train(images, (centres - t_mean) / t_scale, quats)
        arrays = {_WEIGHT_PREFIX + k: v.detach().cpu().numpy() for k, v in net.state_dict().items()}
        arrays.update(t_mean=t_mean, t_scale=np.array([t_scale], np.float32))
        meta = {"config": dataclasses.asdict(c), "frames": len(mapping), "final": final}
        mapfile.write_arrays(map_dir, MAP_FORMAT, MAP_VERSION, arrays, meta)

    def _train(
        self, images: np.ndarray, centres: np.ndarray, quats: np.ndarray
    ) -> tuple[PoseRegressor, dict[str, float]]:
        """Train on (N, H', W', 3) uint8 frames and their normalised centres and quaternions; returns the
        network and its last step's loss terms."""
        c = self.config
        device = torch.device(c.device)
        torch.manual_seed(c.seed)
        gen = torch.Generator().manual_seed(c.seed)
        if device.type == "cuda":
            torch.backends.cudnn.deterministic, torch.backends.cudnn.benchmark = True, False
        net = PoseRegressor(c, pretrained=c.backbone == "encoder").to(device).train()
        s = nn.Parameter(torch.tensor([c.s_x, c.s_q], device=device))
        opt = torch.optim.Adam([*net.parameters(), s], lr=c.lr, weight_decay=c.weight_decay)
        milestones = sorted({round(f * c.steps) for f in c.lr_decay_at})
        sched = torch.optim.lr_scheduler.MultiStepLR(opt, milestones, gamma=0.1)
        x_all = torch.from_numpy(images)  # uint8, cropped per batch before conversion
        t_all, q_all = torch.from_numpy(centres).to(device), torch.from_numpy(quats).to(device)
        h, w = images.shape[1:3]
        for _ in tqdm(range(c.steps), desc="posenet training", leave=False):
            idx = torch.randint(len(images), (min(c.batch_size, len(images)),), generator=gen)
            ys = torch.randint(h - c.input_height + 1, (len(idx),), generator=gen).tolist()
            xs = torch.randint(w - c.input_width + 1, (len(idx),), generator=gen).tolist()
            crops = torch.stack(
                [x_all[i, y : y + c.input_height, x : x + c.input_width] for i, y, x in zip(idx.tolist(), ys, xs)]
            )
            x = jitter(uint8_batch_to_tensor(crops.numpy()) + 0.5, c, gen).to(device) - 0.5
            t_hat, q_hat = net(x)
            l_x = (t_hat - t_all[idx]).norm(dim=1).mean()
            l_q = (q_hat - q_all[idx]).norm(dim=1).mean()
            loss = l_x * torch.exp(-s[0]) + s[0] + l_q * torch.exp(-s[1]) + s[1]
            opt.zero_grad(set_to_none=True)
            loss.backward()
            opt.step()
            sched.step()
        values = (loss, l_x, l_q, s[0], s[1])
        return net.eval(), {k: round(v.item(), 5) for k, v in zip(LOSS_TERMS, values)}

    # ---------------------------------------------------------------------------------- query

    def load_map(self, map_dir: Path) -> None:
        arrays, meta = mapfile.read_arrays(map_dir, MAP_FORMAT, MAP_VERSION)
        meta_path, arrays_path = Path(map_dir) / mapfile.META, Path(map_dir) / mapfile.ARRAYS
        built, own = _network_config(meta.get("config")), _network_config(dataclasses.asdict(self.config))
        if built != own:
            raise DataError(meta_path, f"map built with {built}, this method has {own}")
        net = PoseRegressor(self.config, pretrained=False)
        state = {
            k[len(_WEIGHT_PREFIX) :]: torch.from_numpy(v) for k, v in arrays.items() if k.startswith(_WEIGHT_PREFIX)
        }
        try:
            net.load_state_dict(state)
        except (RuntimeError, KeyError, TypeError, ValueError) as e:
            first = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
            raise DataError(arrays_path, f"weights do not fit the network ({first})") from None
        t_mean, t_scale = arrays.get("t_mean"), arrays.get("t_scale")
        if t_mean is None or t_scale is None or t_mean.shape != (3,) or t_scale.shape != (1,) or not t_scale[0] > 0:
            raise DataError(arrays_path, "malformed translation normalisation (t_mean (3,), t_scale (1,) > 0)")
        self._net = net.to(torch.device(self.config.device)).eval()
        self._t_mean, self._t_scale = t_mean.astype(np.float32), float(t_scale[0])

    @torch.no_grad()
    def localize(self, query: QueryFrame) -> PoseEstimate:
        if self._net is None:
            raise RuntimeError("load_map() must be called before localize()")
        x = uint8_batch_to_tensor(np.ascontiguousarray(self._centre_crop(self._resized(query.color)))[None])
        with single_threaded():
            t, q = self._net(x.to(torch.device(self.config.device)))
        T = np.eye(4)
        T[:3, :3] = Rotation.from_quat(q[0].cpu().numpy().astype(np.float64)).as_matrix()
        T[:3, 3] = self._t_mean + self._t_scale * t[0].cpu().numpy()
        return PoseEstimate(T, {})
