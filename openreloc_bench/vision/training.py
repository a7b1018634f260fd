"""Training and evaluation of the offline encoder's image tower against the frozen MiniLM text tower.

Loss: symmetric InfoNCE between crops and captions, where all crops sharing a caption string are
positives for it, plus an image-image InfoNCE between two views of the same physical object (different
frames, lighting splits), which makes the image embedding discriminative per instance: exactly what
landmark association across views needs.
"""

from __future__ import annotations

import io as _io
import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import torch
import torch.nn.functional as F
from tqdm import tqdm

from openreloc_bench import config as cfgmod
from openreloc_bench.data import mapfile
from openreloc_bench.errors import ConfigError
from openreloc_bench.vision import vocabulary as voc
from openreloc_bench.vision.crops import CropSet
from openreloc_bench.vision.offline import (
    CONFIG_FILE,
    TOWER_FILE,
    WEIGHTS_FORMAT,
    ImageTower,
    TextTower,
    TowerConfig,
    uint8_batch_to_tensor,
)
from openreloc_bench.vision.preprocess import resize_square


@dataclass
class TrainConfig:
    """Hyper-parameters of one training run (saved with the weights)."""

    seed: int = 0
    """Seeds numpy and torch (weights init, batches, augmentation, caption choice)."""
    epochs: int = 6
    """Passes over the training crops (each crop is an anchor once per epoch, or by its repeat factor with
    ``repeat_threshold``, each time with a second view). Held-out crop metrics still rise after 6, but
    relocalization does not follow them, so the epochs were chosen on the validation suite end to end
    (docs/experiments.md); the shipped weights are a 6-epoch run."""
    pairs_per_batch: int = 128
    """Anchors per batch; each brings a second view of its object, so a batch holds twice as many crops."""
    lr: float = 2e-3
    """Peak AdamW learning rate (linear warm-up, cosine decay)."""
    weight_decay: float = 0.05
    """AdamW weight decay."""
    warmup_frac: float = 0.05
    """Share of steps spent warming up."""
    init_temperature: float = 0.07
    """Initial softmax temperature (learned, as in CLIP)."""
    instance_weight: float = 0.3
    """Weight of the two-view image-image loss (0 = text alignment only)."""
    scenes_per_batch: int = 4
    """Anchors of a batch come from this many scenes (0: from all scenes at random). Relocalization
    tells apart the objects of *one* room; with anchors from many scenes the two-view loss's negatives
    are mostly other rooms' objects, which lighting and style already separate. Grouping by scene
    makes them the look-alikes that association confuses."""
    repeat_threshold: float = 0.0
    """Category-balanced sampling (LVIS repeat factors, Gupta et al. 2019): a crop whose category is a share
    f < t of the training crops is an anchor sqrt(t / f) times per epoch on average. The generator's
    categories are long-tailed, and held-out zero-shot accuracy follows the training share. 0 = each
    crop once, the default: balancing lifted the rare categories but lowered the frequent ones more, and
    the per-instance recall that association needs with them."""
    shift_px: int = 6
    """Random translation of crops, in pixels of the tower's input."""
    brightness: float = 0.2
    """Brightness is scaled by a factor in [1 - b, 1 + b]."""
    threads: int = 2
    """torch CPU threads."""
    device: str = "cpu"
    """torch device of the training steps ("cpu", "cuda", "cuda:1"). Augmentation stays on the CPU. A GPU
    run follows the same recipe but not bit for bit (TF32 convolutions, other float sums): the shipped
    weights are the CPU run's. A GPU runs the recipe in minutes instead of the better part of an hour."""


def caption_table(crops: CropSet) -> tuple[list[str], list[list[int]]]:
    """All training captions and, per crop, the indices of the captions true of it.

    Templates mix category, colour and material; the generator's own description is used too, unless
    it contains a held-out synonym (those stay unseen for evaluation).
    """
    held = voc.held_out_words(set(crops.category))
    captions: dict[str, int] = {}
    per_crop: list[list[int]] = []
    cache: dict[tuple[str, str, str, str], list[int]] = {}
    for cat, col, mat, desc in zip(crops.category, crops.colour, crops.material, crops.description):
        key = (cat, col, mat, desc)
        if key not in cache:
            texts = []
            for t in voc.CAPTION_TEMPLATES:
                if ("{colour}" in t and not col) or (("{mat}" in t or "{matn}" in t) and not mat):
                    continue
                texts.append(
                    voc.with_article(
                        t.format(noun=voc.noun(cat), colour=col, mat=voc.MATERIAL_ADJECTIVE.get(mat, mat), matn=mat)
                    )
                )
            if desc and not voc.contains_held_out(desc, held):
                texts.append(desc)
            bad = [x for x in texts if voc.contains_held_out(x, held)]
            if bad:
                raise ValueError(f"training caption uses a held-out synonym: {bad[0]!r}")
            cache[key] = [captions.setdefault(x, len(captions)) for x in dict.fromkeys(texts)]
        per_crop.append(cache[key])
    return list(captions), per_crop


def _augment(images: np.ndarray, rng: np.random.Generator, cfg: TrainConfig) -> torch.Tensor:
    n, s = images.shape[:2]
    p = cfg.shift_px
    padded = np.pad(images, ((0, 0), (p, p), (p, p), (0, 0)), mode="reflect") if p else images
    off = rng.integers(0, 2 * p + 1, size=(n, 2)) if p else np.zeros((n, 2), int)
    out = np.stack([padded[i, off[i, 0] : off[i, 0] + s, off[i, 1] : off[i, 1] + s] for i in range(n)])
    flip = rng.random(n) < 0.5
    out[flip] = out[flip, :, ::-1]
    x = uint8_batch_to_tensor(out) + 0.5
    gain = torch.from_numpy(rng.uniform(1 - cfg.brightness, 1 + cfg.brightness, n).astype(np.float32))
    return (x * gain[:, None, None, None]).clamp_(0, 1) - 0.5


def _soft_ce(logits: torch.Tensor, positives: torch.Tensor) -> torch.Tensor:
    """Cross-entropy against the uniform distribution over each row's positives."""
    target = positives.float() / positives.float().sum(1, keepdim=True)
    return -(target * F.log_softmax(logits, dim=1)).sum(1).mean()


def train_tower(
    crops: CropSet,
    text: TextTower,
    cfg: TrainConfig,
    tower_cfg: TowerConfig | None = None,
    log: Callable[[str], None] = print,
    init: ImageTower | None = None,
) -> tuple[ImageTower, dict[str, Any]]:
    """Train an image tower on ``crops``; return it (eval mode) and a small training history.

    ``init``: a trained tower of the same shape to start from (fine-tuning), instead of random weights.
    """
    if len(crops) < 2:
        raise ValueError(f"need at least 2 training crops, got {len(crops)}")
    tower_cfg = tower_cfg or TowerConfig()
    device = training_device(cfg.device)
    torch.set_num_threads(cfg.threads)
    torch.manual_seed(cfg.seed)
    rng = np.random.default_rng(cfg.seed)
    captions, per_crop = caption_table(crops)
    t0 = time.time()
    text_emb = torch.from_numpy(text.encode(captions)).to(device)
    log(f"{len(captions)} captions encoded in {time.time() - t0:.1f} s")
    keys = crops.instance_keys
    groups: dict[str, list[int]] = {}
    for i, k in enumerate(keys):
        groups.setdefault(k, []).append(i)
    key_id = _key_ids(keys)
    images = (
        crops.images
        if crops.images.shape[1] == tower_cfg.input_size
        else _resize_all(crops.images, tower_cfg.input_size)
    )

    # channels_last: faster convolutions on CPUs (oneDNN's preferred layout)
    tower = ImageTower(tower_cfg)
    if init is not None:
        tower.load_state_dict(init.state_dict())
    tower = tower.to(device, memory_format=torch.channels_last)
    logit_scale = torch.nn.Parameter(torch.tensor(math.log(1 / cfg.init_temperature), device=device))
    opt = torch.optim.AdamW([*tower.parameters(), logit_scale], lr=cfg.lr, weight_decay=cfg.weight_decay)
    n = len(crops)
    half = min(cfg.pairs_per_batch, n)
    # None, not ones, when off: no random draws for repeats, so the batches stay those of the shipped weights
    repeats = repeat_factors(crops.category, cfg.repeat_threshold) if cfg.repeat_threshold > 0 else None
    steps_per_epoch = max(1, (n if repeats is None else int(repeats.sum())) // half)
    scene_of = np.unique(crops.scene, return_inverse=True)[1]
    total = steps_per_epoch * cfg.epochs
    warm = max(1, int(cfg.warmup_frac * total))
    sched = torch.optim.lr_scheduler.LambdaLR(
        opt, lambda s: (s + 1) / warm if s < warm else 0.5 * (1 + math.cos(math.pi * (s - warm) / max(1, total - warm)))
    )
    history: list[dict[str, float]] = []
    tower.train()
    bar = tqdm(total=total, desc="train-encoder", mininterval=5)
    for epoch in range(cfg.epochs):
        losses = []
        for anchor in epoch_batches(scene_of, half, cfg.scenes_per_batch, rng, repeats)[:steps_per_epoch]:
            partner = np.array([_other_view(groups[keys[a]], a, rng) for a in anchor])
            idx = np.concatenate([anchor, partner])
            cap = np.array([per_crop[i][rng.integers(len(per_crop[i]))] for i in idx])
            uniq, inv = np.unique(cap, return_inverse=True)
            x = _augment(images[idx], rng, cfg).to(device).contiguous(memory_format=torch.channels_last)
            emb = F.normalize(tower(x), dim=1)
            scale = logit_scale.exp().clamp(max=100.0)
            logits = scale * emb @ text_emb[torch.from_numpy(uniq).to(device)].T
            inv_t = torch.from_numpy(inv).to(device)
            loss_clip = 0.5 * (
                F.cross_entropy(logits, inv_t)
                + _soft_ce(logits.T, inv_t[None, :] == torch.arange(len(uniq), device=device)[:, None])
            )
            loss = loss_clip
            if cfg.instance_weight > 0:
                ea, eb = emb[: len(anchor)], emb[len(anchor) :]
                ka, kb = torch.from_numpy(key_id[anchor]).to(device), torch.from_numpy(key_id[partner]).to(device)
                same = ka[:, None] == kb[None, :]
                li = scale * ea @ eb.T
                loss = loss + cfg.instance_weight * 0.5 * (_soft_ce(li, same) + _soft_ce(li.T, same.T))
            opt.zero_grad()
            loss.backward()
            opt.step()
            sched.step()
            losses.append(float(loss.detach()))
            bar.update(1)
        history.append(
            {"epoch": epoch + 1, "loss": float(np.mean(losses)), "temperature": float(1 / logit_scale.detach().exp())}
        )
        log(
            f"epoch {epoch + 1}/{cfg.epochs} loss {history[-1]['loss']:.3f} temperature {history[-1]['temperature']:.4f}"
        )
    bar.close()
    return tower.cpu().eval(), {
        "history": history,
        "captions": len(captions),
        "train_seconds": round(time.time() - t0, 1),
    }


def training_device(name: str) -> torch.device:
    """``name`` as a torch device, or a one-line error when it is not one or is not available here."""
    try:
        device = torch.device(name)
    except RuntimeError:
        raise ConfigError(f"unknown torch device {name!r} (use cpu, cuda or cuda:N)") from None
    if device.type == "cuda" and not torch.cuda.is_available():
        raise ConfigError(f"device {name!r} asked for, but torch sees no CUDA GPU here (torch {torch.__version__})")
    if device.type == "cuda" and (device.index or 0) >= torch.cuda.device_count():
        raise ConfigError(f"device {name!r}: torch sees {torch.cuda.device_count()} CUDA GPU(s)")
    if device.type not in ("cpu", "cuda"):
        raise ConfigError(f"device {name!r}: training runs on cpu or cuda")
    return device


def repeat_factors(categories: list[str], threshold: float) -> np.ndarray:
    """Per crop, how many times per epoch it is an anchor on average (see ``TrainConfig.repeat_threshold``)."""
    _, inv, counts = np.unique(np.asarray(categories), return_inverse=True, return_counts=True)
    share = counts / max(1, len(inv))
    return np.maximum(1.0, np.sqrt(threshold / share))[inv] if threshold > 0 else np.ones(len(inv))


def epoch_batches(
    scene_of: np.ndarray, size: int, scenes_per_batch: int, rng: np.random.Generator, repeats: np.ndarray | None = None
) -> list[np.ndarray]:
    """One epoch's anchor batches of ``size`` crop indices, each crop used at most once (or, with
    ``repeats``, floor(r) or ceil(r) times at random, r on average): random over all crops, or, with
    ``scenes_per_batch`` k > 0, k runs of ``size // k`` crops of one scene each (a run may straddle two
    scenes where one scene's crops end)."""
    pool = np.arange(len(scene_of))
    if repeats is not None:
        whole = np.floor(repeats).astype(int)
        pool = np.repeat(pool, whole + (rng.random(len(pool)) < repeats - whole))
    if scenes_per_batch <= 0:
        seq = rng.permutation(pool)
        run, k = size, 1
    else:
        seq = np.concatenate(
            [rng.permutation(pool[scene_of[pool] == sc]) for sc in rng.permutation(scene_of.max() + 1)]
        )
        run = max(1, size // scenes_per_batch)
        k = max(1, size // run)
    runs = [seq[i : i + run] for i in range(0, len(seq) - run + 1, run)]
    order = rng.permutation(len(runs)) if scenes_per_batch > 0 else np.arange(len(runs))
    return [np.concatenate([runs[j] for j in order[i : i + k]]) for i in range(0, len(order) - k + 1, k)] or [seq]


def _key_ids(keys: list[str]) -> np.ndarray:
    table: dict[str, int] = {}
    return np.array([table.setdefault(k, len(table)) for k in keys])


def _resize_all(images: np.ndarray, size: int) -> np.ndarray:
    return np.stack([resize_square(im, size) for im in images])


def _other_view(group: list[int], a: int, rng: np.random.Generator) -> int:
    """Another crop of the same object (itself when it has one view only)."""
    if len(group) == 1:
        return a
    j = group[rng.integers(len(group) - 1)]
    return j if j != a else group[-1]


def _average_precision(scores: np.ndarray, relevant: np.ndarray) -> float:
    order = np.argsort(-scores, kind="stable")
    rel = relevant[order]
    if not rel.any():
        return float("nan")
    hits = np.cumsum(rel)
    return float((hits[rel] / (np.flatnonzero(rel) + 1)).mean())


def evaluate(
    encode_images: Callable[[np.ndarray], np.ndarray],
    encode_texts: Callable[[list[str]], np.ndarray],
    crops: CropSet,
    categories: list[str] | None = None,
) -> dict[str, Any]:
    """Zero-shot category top-1, colour accuracy, cross-view instance recall@1 and unseen-synonym retrieval.

    ``categories``: the label set for zero-shot (default: those in ``crops``). Instance retrieval uses
    one ``mapping`` view per object as the gallery and every other-split view as a query, both within
    each scene (what relocalization needs) and over all eval objects pooled.
    """
    E = encode_images(crops.images)
    cats = sorted(set(categories or crops.category) | set(crops.category))
    T = encode_texts([voc.with_article(voc.ZERO_SHOT_TEMPLATE.format(noun=voc.noun(c))) for c in cats])
    true = np.array([cats.index(c) for c in crops.category])
    pred = (E @ T.T).argmax(1)
    per_cat = {c: float((pred[true == k] == k).mean()) for k, c in enumerate(cats) if (true == k).any()}
    out: dict[str, Any] = {
        "crops": len(crops),
        "objects": len(set(crops.instance_keys)),
        "scenes": len(set(crops.scene)),
        "zero_shot_top1": float((pred == true).mean()),
        "zero_shot_top1_per_category": per_cat,
    }
    # colour, given the category (the describer picks colour after the noun)
    colours = sorted({c for c in crops.colour if c})
    if colours:
        correct = []
        for cat in sorted(set(crops.category)):
            rows = [i for i, (c, col) in enumerate(zip(crops.category, crops.colour)) if c == cat and col]
            if rows:
                Tc = encode_texts([voc.with_article(f"a {col} {voc.noun(cat)}") for col in colours])
                p = (E[rows] @ Tc.T).argmax(1)
                correct += [colours[k] == crops.colour[i] for k, i in zip(p, rows)]
        out["colour_top1_given_category"] = float(np.mean(correct))
    out.update(_instance_recall(E, crops))
    thumbs = np.stack([np.asarray(_thumb(im), np.float32).ravel() for im in crops.images])
    thumbs -= thumbs.mean(1, keepdims=True)
    out["baseline_8x8_thumbnail"] = _instance_recall(
        thumbs / np.linalg.norm(thumbs, axis=1, keepdims=True).clip(1e-6), crops
    )
    # unseen synonyms
    syn: dict[str, Any] = {}
    for cat, words in voc.HELD_OUT_SYNONYMS.items():
        if cat not in crops.category:
            continue
        k = cats.index(cat)
        for w in words:
            if w in {voc.noun(c) for c in cats}:
                continue  # a real category here, not an unseen word
            labels = [voc.ZERO_SHOT_TEMPLATE.format(noun=w if i == k else voc.noun(c)) for i, c in enumerate(cats)]
            Ts = encode_texts([voc.with_article(x) for x in labels])
            ps = (E[true == k] @ Ts.T).argmax(1)
            ap = _average_precision(E @ Ts[k], true == k)
            syn[f"{w} ({cat})"] = {"zero_shot_top1": float((ps == k).mean()), "ap": ap}
    if syn:
        out["synonyms"] = syn
        out["synonym_zero_shot_top1_mean"] = float(np.mean([v["zero_shot_top1"] for v in syn.values()]))
        out["synonym_ap_mean"] = float(np.mean([v["ap"] for v in syn.values()]))
    return out


def _thumb(im: np.ndarray) -> np.ndarray:
    return cv2.resize(im, (8, 8), interpolation=cv2.INTER_AREA)


def _instance_recall(E: np.ndarray, crops: CropSet) -> dict[str, Any]:
    keys = crops.instance_keys
    gallery: dict[str, int] = {}
    for i, (k, s) in enumerate(zip(keys, crops.split)):
        if s == "mapping":
            gallery.setdefault(k, i)
    queries = [i for i, (k, s) in enumerate(zip(keys, crops.split)) if s != "mapping" and k in gallery]
    if not queries or len(gallery) < 2:
        return {}
    gk = list(gallery)
    G = E[[gallery[k] for k in gk]]
    sims = E[queries] @ G.T
    qk = [keys[i] for i in queries]
    pooled = np.mean([gk[j] == k for j, k in zip(sims.argmax(1), qk)])
    scene_of = np.array([k.split("/")[0] for k in gk])
    within = []
    for row, k in zip(sims, qk):
        row = np.where(scene_of == k.split("/")[0], row, -np.inf)
        within.append(gk[int(row.argmax())] == k)
    return {
        "instance_recall1_within_scene": float(np.mean(within)),
        "instance_recall1_pooled": float(pooled),
        "instance_gallery_pooled": len(gk),
        "instance_gallery_per_scene_mean": float(len(gk) / len(set(scene_of))),
        "instance_queries": len(queries),
    }


def save_weights(out_dir: Path, tower: ImageTower, tower_cfg: TowerConfig, meta: dict[str, Any]) -> None:
    """fp16 state dict + config.json (tower shape, text model, training config and data seeds), written
    as the checksummed file set :func:`~openreloc_bench.vision.offline.load_tower` reads."""
    buf = _io.BytesIO()
    torch.save({k: (v.half() if v.is_floating_point() else v) for k, v in tower.state_dict().items()}, buf)
    config = mapfile.json_bytes({**meta, "tower": cfgmod.to_dict(tower_cfg)})
    mapfile.write_file_set(out_dir, *WEIGHTS_FORMAT, {TOWER_FILE: buf.getvalue(), CONFIG_FILE: config})
