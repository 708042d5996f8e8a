"""The ``[binpf]`` parameters, declared once (:mod:`onebit.core.params`): :class:`BinPFConfig`,
the stage's, and :class:`FilterParams`, the filter's -- the same declarations (defaults, docs,
bounds) taken from :class:`BinPFConfig`, in site units, plus what the stage resolves: the frame
``period``, ``max_tracks`` and ``max_out`` from ``targets``
(:func:`onebit.trackers.binpf.stage.filter_params`)."""

from __future__ import annotations

from dataclasses import dataclass

from onebit.core.errors import ConfigError
from onebit.core.params import derived, param, validate
from onebit.core.units import length


@dataclass(frozen=True, kw_only=True)
class BinPFConfig:
    """``run.toml`` ``[binpf]``. Defaults fit the real ceiling IR array of Milan et al. (fitted
    by maximum likelihood of Eq. (2) on its sequence r1-easy: :math:`p_d` 0.74, soft edge
    0.31 m, :math:`p_f` 0.008; see ``docs/binpf.md``)."""

    particles: int = param(300, "particles per track", lo=1, hi=10**6)
    pd: float = param(
        0.75, "p_d, probability a person well inside a footprint triggers the sensor in a frame", lo=1e-6, hi=1.0
    )
    pf: float = param(0.01, "p_f, probability a sensor is on with nobody near (false alarm) per frame", lo=1e-9, hi=0.5)
    edge: float = length(0.3, "w, width of the footprint's soft edge (0 = hard disk)", lo=0.0, hi=1e6)
    radius: float | None = length(
        None, "footprint radius R_s for every sensor; unset = each sensor's r_outer", lo=1e-9, hi=1e9
    )
    damping: float = param(0.8, "a, velocity kept from one frame to the next", lo=0.0, hi=1.0)
    accel_sigma: float = length(0.8, "sigma_v, velocity noise per sqrt(s)", unit="m/s", lo=0.0, hi=1e6)
    survival: float = param(0.98, "p_s, probability a person stays from one frame to the next", lo=1e-6, hi=1.0)
    silent: float = param(
        0.3, "epsilon, probability a present person triggers nothing in a frame (Eq. 4')", lo=0.0, hi=0.999
    )
    birth_r: float = param(0.1, "existence of a newborn track", lo=1e-6, hi=0.999)
    birth_explained: float = param(
        0.3, "an on sensor the tracks trigger with less than this is unexplained", lo=0.0, hi=1.0
    )
    birth_link: float = length(1.8, "unexplained on sensors closer than this give one newborn", lo=0.0, hi=1e9)
    birth_speed: float = length(0.3, "std of a newborn particle's velocity", unit="m/s", lo=0.0, hi=1e6)
    r_confirm: float = param(0.9, "a track is confirmed once its existence reaches this", lo=0.0, hi=1.0)
    r_delete: float = param(0.05, "a track is deleted when its existence falls below this", lo=0.0, hi="r_confirm")
    r_out: float = param(
        0.65, "a confirmed track is reported while its existence is at least this", lo="r_delete", hi=1.0
    )
    merge_distance: float = length(0.4, "two tracks closer than this are merged", lo=0.0, hi=1e9)
    split_ratio: float = param(
        0.0, "a twin of a track is proposed where its likelihood ratio is at least this; 0 = no split", lo=0.0, hi=1e9
    )
    count_ratio: float = param(
        0.0,
        "kappa of Eq. (8), the local MAP count's price per person (untracked ones born, binpf.md); 0 = off",
        lo=0.0,
        hi=1e9,
    )
    joint_distance: float = length(
        0.0,
        "tracks whose means are closer than this are updated in pairs by the joint likelihood "
        "(binpf/joint.py, Eqs. 11-13) instead of the mean field; 0 = off",
        lo=0.0,
        hi=1e9,
    )
    joint_ratio: float = param(
        2.0,
        "kappa_j of Eq. (13): a joint pair's labels are ordered, and the pair not merged, where two "
        "people explain the frame this many times better than one",
        lo=1.0,
        hi=1e9,
    )
    joint_met: bool = param(
        False,
        "the joint update only for pairs that met: both confirmed and at least joint_distance apart before "
        "they first came closer (binpf/joint.py, Eq. 14); a newborn beside a track keeps the mean field",
    )
    evidence_ratio: float = param(
        0.0,
        "kappa of Eq. (10): report a row of a once-reported track where the sensors' support over "
        "+-evidence_window frames is at least log kappa, instead of r >= r_out (binpf/evidence.py); 0 = off",
        lo=0.0,
        hi=1e9,
    )
    evidence_window: int = param(
        2, "h of Eq. (10), frames either side summed in a row's support", lo=0, hi=1000, unit="frames"
    )
    smooth_lag: int = param(
        4,
        "fixed-lag smoothing of the positions (particle genealogy); 0 = filter only",
        lo=0,
        hi=1000,
        unit="frames",
    )
    link: bool = param(True, "join tracklets across short gaps (one min-cost assignment, binpf/link.py)")
    link_gap: int = param(10, "g_max, most missing frames a join bridges", lo=0, hi=10**6, unit="frames")
    link_speed: float = length(1.5, "v_max, walking speed a join may assume", unit="m/s", lo=0.0, hi=1e6)
    link_slack: float = length(1.0, "rho, extra distance a join allows (about a footprint)", lo=0.0, hi=1e9)
    commit_lag: int = param(
        0,
        "frames after which a frame's tracks are final; 0 = the whole log (a confirmed track is reported "
        "back to its birth, tracklets joined over the run); > 0 (at least smooth_lag): reported if "
        "confirmed within the lag, joined causally -- what `onebit follow` publishes, equal with the same "
        "value (binpf/online.py)",
        lo=0,
        hi=10**6,
        unit="frames",
    )
    targets: int = param(0, "most people reported at once; 0 = the site's targets (none: no bound)", lo=0, hi=10**4)
    max_tracks: int = param(
        0,
        "most live tracks (tentative included); 0 = bound + 1 (8 without a bound): spare tentative tracks churn",
        lo=0,
        hi=10**4,
    )
    seed: int = param(0, "random seed", lo=0)
    log_particles: int = param(50, "particles per track and frame sent to Rerun", lo=0, hi=10**6)
    log_particles_max: int = param(
        2_000_000,
        "most particles sent to Rerun over the run: on a long log each track sends "
        "min(log_particles, max(1, log_particles_max // (frames x max_tracks))) a frame "
        "(50 a frame on 475 000 frames of 6 tracks would be 142 million points, 4.6 GB)",
        lo=0,
        hi=10**9,
    )
    max_frames: int = param(
        250_000,
        "the most frames the pipeline runs it on; a longer log skips the stage, saying so (each frame costs "
        "~0.35 ms of CPU with the default particles -- the stage on 47 499 frames of the simulated 25-sensor "
        "line, cold, on 2 shared cores: 16.1-17.0 s; 157 s on 474 999 -- so 250 000 frames take about "
        "1.5 minutes); 0 = no bound",
        lo=0,
        unit="frames",
    )

    def __post_init__(self) -> None:
        validate(self)
        if self.commit_lag and self.commit_lag < self.smooth_lag:
            raise ConfigError(
                f"BinPFConfig.commit_lag = {self.commit_lag}: must be 0 or at least smooth_lag = {self.smooth_lag} "
                "(a frame's smoothed positions are final smooth_lag frames later)"
            )
        if self.commit_lag and self.count_ratio:
            raise ConfigError(
                f"BinPFConfig.count_ratio = {self.count_ratio}: the count runs in the batch filter only; "
                "set commit_lag = 0 (the online driver has no count)"
            )
        if self.commit_lag and self.joint_distance:
            raise ConfigError(
                f"BinPFConfig.joint_distance = {self.joint_distance}: the joint update runs in the batch filter "
                "only; set commit_lag = 0 (the online driver has no joint update)"
            )
        if self.joint_met and not self.joint_distance:
            raise ConfigError(
                "BinPFConfig.joint_met = true: it restricts the joint update, which is off; set joint_distance > 0"
            )
        if self.commit_lag and self.evidence_ratio:
            raise ConfigError(
                f"BinPFConfig.evidence_ratio = {self.evidence_ratio}: the evidence rule reads frames after a row, "
                "so it runs in the batch stage only; set commit_lag = 0"
            )


#: The config's fields the filter reads (:func:`onebit.trackers.binpf.filter.run_filter`).
FILTER_FIELDS = (
    "particles", "pd", "pf", "edge", "damping", "accel_sigma", "survival", "birth_r", "birth_explained",
    "birth_link", "birth_speed", "r_confirm", "r_delete", "r_out", "merge_distance", "silent", "smooth_lag",
    "max_tracks", "split_ratio", "count_ratio", "joint_distance", "joint_ratio", "joint_met",
)  # fmt: skip

FilterParams = derived(
    "FilterParams",
    BinPFConfig,
    FILTER_FIELDS,
    defaults={"max_tracks": 12},  # the filter's own bound (the config's 0 = derived from targets)
    extra={
        "period": param(0.5, "seconds between frames (the frames' own spacing)", lo=1e-9, unit="s"),
        "max_out": param(0, "most tracks reported at once; 0 = no bound", lo=0, hi=10**4),
        "couple_distance": param(
            2.5, "a couple (split twins) ends when their means are farther apart than this (site units)", lo=0.0
        ),
        "count_persist": param(
            2, "the count births a place also found the frame before (>= 2) or at once (1)", lo=1, hi=2
        ),
    },
    doc="Parameters of :func:`onebit.trackers.binpf.filter.run_filter` in site units: "
    ":class:`BinPFConfig`'s declarations of the same names (``max_tracks`` resolved, 12 by default) "
    "plus ``period``, ``max_out``, ``couple_distance`` and ``count_persist``.",
    module=__name__,
)
