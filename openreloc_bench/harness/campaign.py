"""A leaderboard campaign: every method on every benchmark suite, track, split and seed, at one code version.

The campaign is a list of steps, each one ``eval`` call (one suite, track and method; its splits and
seeds), ordered so that an interrupted or partial campaign already holds the most useful rows: first
the query split of every method on both tracks, then the robustness splits, then the further seeds of the query split,
then the ablations. Each finished step is recorded in ``WORK/campaign.json`` with its wall time; a
second run at the same code version (:func:`cache.git_commit`: the last commit that changed the code)
skips recorded steps (and, inside a step, ``eval``'s finished jobs), and a run at another code version is
refused, so every row of the boards it renders comes from one version of the code, even when boards of a
run that spans several sittings are committed as its steps finish.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import pandas as pd

from openreloc_bench import config, plugins
from openreloc_bench.data import io, paths
from openreloc_bench.data.splits import QUERY_SPLITS
from openreloc_bench.errors import ConfigError, DataError
from openreloc_bench.harness import cache, runner
from openreloc_bench.harness.ablations import ABLATED_METHOD
from openreloc_bench.harness.evaluation import tabulate
from openreloc_bench.harness.suites import ensure_suite_scenes
from openreloc_bench.methods import recorded_track, uses_masks
from openreloc_bench.tracks import TRACKS

STAGES = ("headline", "robustness", "seeds", "ablations")
"""The campaign's stages, in the order they run (each a priority: a partial campaign has the first)."""


@dataclass
class CampaignPlan:
    """What a campaign runs (``leaderboard/plan.yaml`` is the one behind the committed boards)."""

    suites: list[str] = field(default_factory=lambda: ["multi-room", "multi-floor", "single-room"])
    """Benchmark suites by name (``<suite_dir>/<name>.yaml``). Validation suites are refused: they are
    for choosing settings and are never reported."""
    suite_dir: str = "scenes"
    """Folder holding the suite YAMLs (relative to the working directory)."""
    card_dir: str = "docs/cards"
    """Folder holding the suites' dataset cards (``openreloc-bench card``): each board links
    ``<card_dir>/<suite>.md`` where it is there."""
    methods: list[str] = field(default_factory=list)
    """Registered method names, each run on every suite: the plan names them (no list here to fall out of
    step with it)."""
    oracle_only: list[str] = field(default_factory=list)
    """Diagnostics that read the dataset's masks at query time: where the plan runs them, they run on the
    oracle-mask track only."""
    tracks: list[str] = field(default_factory=lambda: ["predicted", "oracle-mask"])
    """Tracks, headline first. Methods that read no masks run on the first only (their rows stand in both
    tables)."""
    splits: list[str] = field(default_factory=lambda: list(QUERY_SPLITS))
    """Query splits; the first is the headline split, the others are the robustness stage."""
    seeds: list[int] = field(default_factory=lambda: [0, 1, 2])
    """Seeds of the seeded methods; the first runs in the headline and robustness stages, the others in
    the seeds stage, on the headline split (deterministic methods run once)."""
    ablation_suites: list[str] = field(default_factory=lambda: ["multi-room"])
    """Suites on which the paper's ablation rows of OpenReLoc run (headline split, first seed)."""
    ablation_track: str = "oracle-mask"
    """Track of the ablation rows (the upper bound isolates each part from the segmenter's errors)."""
    serial_methods: list[str] = field(default_factory=list)
    """Methods whose jobs run one at a time under the local executor: each trains with every core, and
    beside another job it is several times slower."""
    plugins: list[str] = field(default_factory=list)
    """Plugins to import first: module names or ``.py`` files relative to the working directory, whose
    import registers methods with ``openreloc_bench.methods.register``."""
    estimate_h: dict[str, float] = field(default_factory=dict)
    """The plan's estimate of each stage's wall time [h] (keys from :data:`STAGES`), printed beside the
    measured time in ``campaign.md``, so a run says how far the estimate was off."""


@dataclass(frozen=True)
class Step:
    """One ``eval`` call of the campaign."""

    stage: str
    suite: str
    track: str
    method: str
    splits: tuple[str, ...]
    seeds: tuple[int, ...]
    ablations: bool = False

    @property
    def key(self) -> str:
        return f"{self.stage}/{self.suite}/{self.track}/{self.method}"

    def record(self) -> dict[str, Any]:
        return {k: list(v) if isinstance(v, tuple) else v for k, v in asdict(self).items()}


def load_plan(path: Path) -> CampaignPlan:
    """A plan YAML, checked: known suites, tracks, splits, methods and plugins, distinct seeds."""
    plan = config.from_dict(CampaignPlan, config.load_mapping(path), "plan")
    check_plan(plan)
    return plan


def check_plan(plan: CampaignPlan) -> None:
    """One-line errors for a plan that cannot run, before any work."""
    from generators.spec import load_suite

    plugins.load_plugins(plan.plugins)
    for what, names in (("suites", plan.suites), ("methods", plan.methods), ("tracks", plan.tracks)):
        if not names or len(set(names)) != len(names):
            raise ConfigError(f"plan: '{what}' must name at least one entry, each once")
    if not plan.splits or len(set(plan.splits)) != len(plan.splits) or not plan.seeds:
        raise ConfigError("plan: 'splits' and 'seeds' must name at least one entry, splits each once")
    for stage, hours in plan.estimate_h.items():
        if stage not in STAGES or not math.isfinite(hours) or hours < 0:
            raise ConfigError(
                f"plan: estimate_h takes hours >= 0 of the stages {', '.join(STAGES)}, got {stage}: {hours}"
            )
    for track in {*plan.tracks, plan.ablation_track}:
        if track not in TRACKS:
            raise ConfigError(f"plan: unknown track '{track}' (known: {', '.join(TRACKS)})")
    wrong = [s for s in plan.splits if s not in QUERY_SPLITS]
    if wrong:
        raise ConfigError(f"plan: unknown split '{wrong[0]}' (known: {', '.join(QUERY_SPLITS)})")
    runner.seeded_runs([runner.MethodRun(m, m) for m in plan.methods], plan.seeds)  # unknown methods, seeds
    for name in {*plan.suites, *plan.ablation_suites}:
        if name not in plan.suites:
            raise ConfigError(f"plan: ablation suite '{name}' is not one of the plan's suites")
        path = suite_path(plan, name)
        if not path.is_file():
            raise ConfigError(f"plan: no suite file {path}")
        if load_suite(path).purpose != "benchmark":
            raise ConfigError(f"plan: {path} is a validation suite: choose settings on it, never report it")


def suite_path(plan: CampaignPlan, name: str) -> Path:
    return Path(plan.suite_dir) / f"{paths.plain_name(name, 'suite')}.yaml"


def is_seeded(method: str) -> bool:
    return len(runner.seeded_runs([runner.MethodRun(method, method)], [0, 1])) > 1


def plan_steps(plan: CampaignPlan) -> list[Step]:
    """The campaign's steps in the order they run."""
    first, rest = plan.splits[:1], plan.splits[1:]
    steps = []
    masked = {m: uses_masks(m) for m in plan.methods}  # each answer instantiates or looks up the method

    def per_method(stage: str, splits: list[str], seeds: list[int], methods: list[str]) -> None:
        for suite in plan.suites:
            for track in plan.tracks:
                for m in methods:
                    if m in plan.oracle_only and track != "oracle-mask":
                        continue
                    if masked[m] or track == plan.tracks[0]:
                        steps.append(Step(stage, suite, track, m, tuple(splits), tuple(seeds)))

    per_method("headline", first, plan.seeds[:1], plan.methods)
    if rest:
        per_method("robustness", rest, plan.seeds[:1], plan.methods)
    if len(plan.seeds) > 1:
        per_method("seeds", first, plan.seeds, [m for m in plan.methods if is_seeded(m)])
    steps += [
        Step("ablations", s, plan.ablation_track, ABLATED_METHOD, tuple(first), tuple(plan.seeds[:1]), True)
        for s in plan.ablation_suites
    ]
    return steps


@dataclass
class CampaignConfig:
    """One ``openreloc-bench campaign`` invocation."""

    plan: CampaignPlan
    """What to run."""
    data: Path
    """Dataset folder (suites generated into it where missing)."""
    work: Path
    """Results of every step (one results folder per suite) and ``campaign.json``."""
    out: Path
    """Where the boards go (one folder per suite, plus ``campaign.md``)."""
    executor: str = "local"
    """``local`` or ``ray``."""
    workers: int = 2
    """Parallel jobs of each step (local executor)."""
    ray_address: str | None = None
    """Existing Ray cluster (default: ``RAY_ADDRESS`` or a local instance)."""
    allow_dirty: bool = False
    """Run from a working tree with uncommitted changes (a trial: its rows name no checkout-able commit)."""
    render_only: bool = False
    """Render the boards from the finished steps; run nothing."""
    screenshot: bool = True
    """Save a screenshot of each board's HTML page (when a headless Chromium is installed)."""
    verdict_into: list[Path] = field(default_factory=list)
    """READMEs whose block between the verdict markers (``campaign_page.VERDICT_BEGIN`` / ``VERDICT_END``)
    is replaced with the verdict table of the boards rendered."""


class Ledger:
    """``WORK/campaign.json``: the campaign's code version, and each finished step with its wall time
    (``wall_s`` of the sitting that finished it, ``earlier_s`` of sittings that ended it mid-way).

    ``commit`` is the checkout's code version: a ledger begun at another is refused, since its rows and new
    ones would mix. ``None`` opens it whatever its commit, to read it only (``--list`` from another checkout).
    """

    def __init__(self, work: Path, commit: str | None):
        self.path = work / "campaign.json"
        self.data: dict[str, Any] = {"commit": commit, "steps": {}}
        if self.path.is_file():
            self.data = io.read_json(self.path)
            if not isinstance(self.data, dict) or not isinstance(self.data.get("steps"), dict):
                raise DataError(self.path, "not a campaign record (remove it to start the campaign afresh)")
            if commit is not None and self.data.get("commit") != commit:
                raise ConfigError(
                    f"{work} holds a campaign run at commit {self.data.get('commit')}, this checkout's code is at {commit}: "
                    "check that commit out to go on with it, or give another --work"
                )

    def done(self, step: Step) -> bool:
        rec = self.data["steps"].get(step.key)
        return bool(rec) and rec["step"] == step.record() and not rec["errors"]

    def add(self, key: str, rec: dict[str, Any]) -> None:
        self.data["steps"][key] = rec
        io.write_json(self.path, self.data)

    def interrupted(self, key: str, seconds: float) -> None:
        """Keep the wall time a step ran before a sitting ended it: its record counts it when it finishes."""
        earlier = self.data.setdefault("interrupted_s", {})
        earlier[key] = earlier.get(key, 0.0) + seconds
        io.write_json(self.path, self.data)


def list_steps(plan: CampaignPlan, work: Path, say: Callable[[str], None] = print) -> None:
    """Say each of the plan's steps and whether ``work``'s record holds it done, and how many are done
    (and about how long the rest take); a record of any commit is read, and one of another says so."""
    ledger = Ledger(work, None) if (work / "campaign.json").is_file() else None
    if ledger and ledger.data.get("commit") != cache.git_commit():
        say(f"{work} holds a campaign run at commit {ledger.data.get('commit')}, not this checkout's")
    steps = plan_steps(plan)
    done = [bool(ledger and ledger.done(step)) for step in steps]
    for k, (step, is_done) in enumerate(zip(steps, done, strict=True), 1):
        state = "done" if is_done else "to run"
        say(f"{k:3d}/{len(steps)} {state:6s} {step.key}: {', '.join(step.splits)}; seeds {list(step.seeds)}")
    n_done = sum(done)
    left = remaining_s(steps, ledger) if ledger else None
    say(f"{n_done} of {len(steps)} steps done{left_text(left) if n_done < len(steps) else ''}")


def run_campaign(cfg: CampaignConfig, say: Callable[[str], None] = print) -> int:
    """Run the plan's missing steps, then render the boards; returns the number of steps with errors."""
    check_plan(cfg.plan)
    commit = cache.git_commit()
    if (commit.endswith("-dirty") or commit == "unknown") and not cfg.allow_dirty:
        raise ConfigError(
            f"the checkout is at {commit}: a board names the commit its rows come from; "
            "commit first (or --allow-dirty for a trial run)"
        )
    if cfg.workers < 1:
        raise ConfigError("--workers must be >= 1")
    from openreloc_bench.harness.leaderboard import campaign_page

    campaign_page.check_verdict_files(cfg.verdict_into)
    cfg.work.mkdir(parents=True, exist_ok=True)
    with paths.directory_lock(cfg.work, "openreloc-bench campaign"):
        ledger = Ledger(cfg.work, commit)
        failed = 0 if cfg.render_only else _run_steps(cfg, ledger, say)
        render(cfg, ledger, say)
    return failed


def _run_steps(cfg: CampaignConfig, ledger: Ledger, say: Callable[[str], None]) -> int:
    steps = plan_steps(cfg.plan)
    scenes: dict[str, list[str]] = {}
    failed = 0
    for k, step in enumerate(steps, 1):
        if ledger.done(step):
            continue
        if step.suite not in scenes:
            t0 = time.perf_counter()
            scenes[step.suite] = ensure_suite_scenes(suite_path(cfg.plan, step.suite), cfg.data)
            if f"generate/{step.suite}" not in ledger.data["steps"]:
                ledger.add(f"generate/{step.suite}", {"wall_s": time.perf_counter() - t0, "errors": []})
        say(f"[{k}/{len(steps)}] {step.key}: {', '.join(step.splits)}; seeds {', '.join(map(str, step.seeds))}"
            f"{left_text(remaining_s(steps, ledger))}")  # fmt: skip
        serial = cfg.executor == "local" and step.method in cfg.plan.serial_methods
        ecfg = runner.EvalConfig(
            data=cfg.data, out=cfg.work / step.suite, scenes=scenes[step.suite],
            runs=runner.variant_runs([step.method], {}, step.ablations), splits=list(step.splits),
            track=step.track, executor=cfg.executor, workers=1 if serial else cfg.workers,
            ray_address=cfg.ray_address, resume=True, plugins=cfg.plan.plugins, seeds=list(step.seeds),
        )  # fmt: skip
        t0 = time.perf_counter()
        try:
            report = runner.evaluate(ecfg)
        except KeyboardInterrupt:
            ledger.interrupted(step.key, time.perf_counter() - t0)
            raise
        for err in report.errors:
            say(f"error: {err}")
        failed += bool(report.errors)
        earlier_s = ledger.data.get("interrupted_s", {}).pop(step.key, 0.0)  # sittings that ended mid-step
        ledger.add(step.key, {"step": step.record(), "wall_s": report.wall_s, "earlier_s": earlier_s,
                              "errors": report.errors, "queries": report.queries, "maps_built": report.maps_built,
                              "maps_s": report.maps_s})  # fmt: skip
    return failed


def new_jobs(steps: list[Step]) -> list[int]:
    """How many (variant, split, seed) runs per scene each step adds to the ones before it: ``eval``
    skips what an earlier step of the same suite and track finished (the seeds stage repeats seed 0)."""
    seen: set[tuple[str, str, str, str, int]] = set()
    counts = []
    for s in steps:
        labels = [r.label for r in runner.variant_runs([s.method], {}, s.ablations)]
        jobs = {(s.suite, s.track, lab, sp, sd) for lab in labels for sp in s.splits for sd in s.seeds} - seen
        seen |= jobs
        counts.append(len(jobs))
    return counts


def new_maps(steps: list[Step]) -> list[int]:
    """How many map configs (:func:`cache.map_key`, each one map per scene) each step builds that no step
    before it does: the seeds stage builds new maps only for methods whose map depends on the seed (a
    trained pose regressor), and the ablations of the query stages share the full method's map."""
    seen: set[tuple[str, str]] = set()
    counts = []
    for s in steps:
        runs = runner.seeded_runs(runner.variant_runs([s.method], {}, s.ablations), list(s.seeds))
        keys = {(s.suite, cache.map_key(m, recorded_track(m, s.track))) for _, m in runs} - seen
        seen |= keys
        counts.append(len(keys))
    return counts


def remaining_s(steps: list[Step], ledger: Ledger) -> float | None:
    """About how long the unfinished steps take at the pace of the finished ones: query time per new run
    (:func:`new_jobs`) plus map-building time per new map config (:func:`new_maps`), each taken from the
    same method on the same suite, else any method on that suite, else any step. None before a step has
    finished. Records without ``maps_s`` (written before it existed) are left out: they cannot tell map
    time from query time."""
    jobs = dict(zip([s.key for s in steps], new_jobs(steps), strict=True))
    maps = dict(zip([s.key for s in steps], new_maps(steps), strict=True))
    recs = ledger.data["steps"]
    done = {s.key: (s, recs[s.key]) for s in steps if ledger.done(s) and "maps_s" in recs[s.key]}
    if not done:
        return None

    def pace(
        step: Step, spent: Callable[[dict[str, Any]], float], units: Callable[[Step, dict[str, Any]], float]
    ) -> float:
        """Seconds per unit over the finished steps most like ``step`` (``spent`` and ``units`` of each)."""
        for like in (lambda x: (x.suite, x.method), lambda x: x.suite, lambda x: None):
            picked = [(d, rec) for d, rec in done.values() if units(d, rec) and like(d) == like(step)]
            if picked:
                return sum(spent(rec) for _, rec in picked) / sum(units(d, rec) for d, rec in picked)
        return 0.0

    total = 0.0
    for s in steps:
        if s.key not in done:
            total += jobs[s.key] * pace(s, lambda r: r["wall_s"] - r["maps_s"], lambda d, r: jobs[d.key])
            total += maps[s.key] * pace(
                s, lambda r: r["maps_s"], lambda d, r: maps[d.key] * (r.get("maps_built", 0) > 0)
            )
    return total


def left_text(left_s: float | None) -> str:
    """``remaining_s`` for people (empty before a step has finished)."""
    return "" if left_s is None else f" (about {left_s / 3600:.1f} h left at the pace so far)"


def render(cfg: CampaignConfig, ledger: Ledger, say: Callable[[str], None]) -> None:
    """Every suite's board from its results folder, the campaign page and, where Chromium is installed,
    a screenshot of each board."""
    from openreloc_bench.harness import browser
    from openreloc_bench.harness.leaderboard import PAIRED_FILE, campaign_page, write_leaderboard

    summaries, comparisons = [], []
    for suite in cfg.plan.suites:
        results = cfg.work / suite
        if tabulate(results) is None:
            continue
        board = cfg.out / suite
        card = Path(cfg.plan.card_dir) / f"{suite}.md"
        write_leaderboard([results], board, cfg.data, card if card.is_file() else None)
        summaries.append(pd.read_csv(board / "leaderboard.csv").assign(suite=suite))
        comparisons.append(pd.read_csv(board / PAIRED_FILE).assign(suite=suite))
        if cfg.screenshot and browser.available():
            browser.screenshot(board / "index.html", board / "screenshot.png")
        elif cfg.screenshot:
            say(f"no screenshot of {board / 'index.html'}: {browser.MISSING}")
    steps = plan_steps(cfg.plan)
    pending = [s.key for s in steps if not ledger.done(s)]
    rows = pd.concat(summaries) if summaries else pd.DataFrame()
    text = campaign_page.campaign_page(
        ledger.data, rows, pending, STAGES, cfg.plan, left_text(remaining_s(steps, ledger))
    )
    io.atomic_write_text(cfg.out / "campaign.md", text)
    say(text.split("\n## Summary")[0].rstrip())
    if not rows.empty:
        for readme in cfg.verdict_into:
            block = campaign_page.verdict_block(
                rows, pd.concat(comparisons), cfg.plan, cfg.out.resolve(), readme, ledger.data["commit"], len(pending)
            )
            campaign_page.write_verdict(readme, block)
            say(f"verdict written into {readme}")
    say(f"boards in {cfg.out}")
