"""The shared configuration of the HMM trackers (``findinghumo``, ``hmm1``, ``hmm2``,
``findinghumo-flow``): :class:`HmmConfig`, declared once (:func:`onebit.core.params.param`); the
window decoder's parameters (:class:`onebit.models.graph_hmm.adaptive.DecoderParams`) are
derived from it."""

from __future__ import annotations

from dataclasses import dataclass

from onebit.core.errors import ConfigError
from onebit.core.frames import ABSENT_AFTER_S
from onebit.core.params import param, validate

#: Slots after an exit in which an entry at the same door continues that user (the window decoder).
RESUME_SLOTS = 10

#: how the run is decoded (:attr:`HmmConfig.decoding`)
DECODINGS = ("batch", "lagged")

#: where the joint re-decoding of meetings runs (:attr:`HmmConfig.joint`)
JOINT = ("off", "before-cpda", "after-cpda")


@dataclass(frozen=True, kw_only=True)
class HmmConfig:
    """Shared configuration of the HMM trackers (``run.toml`` sections ``[findinghumo]``,
    ``[hmm1]``, ``[hmm2]``, ``[findinghumo-flow]``); defaults are the paper's (section IV-A). The
    trackers work on the sensor graph: no field is a length."""

    period: float = param(1.0, "length T of a unit timeslot", lo=1e-3, unit="s")
    sampling: str = param(
        "mid",
        "how the binary series becomes b_j(t) per slot: mid -- the state at the slot's mid time (short "
        "on-periods kept in their own slot) -- or any -- on at some time in the slot (slot_activity)",
        choices=("mid", "any"),
    )
    d_max: int = param(5, "HMM window length (d_max T = 5 s)", lo=1, hi=1000, unit="slots")
    tau: int = param(
        3,
        "acceptance threshold: the first tau slots of a window are kept, the next window starts there (the "
        "paper does not give a value)",
        lo=1,
        hi="d_max",
        unit="slots",
    )
    eatg: str = param(
        "trained",
        "trained -- A', A'' learned from the run's own motion data (eqs. 1, 2), smoothed with the layout -- "
        "layout (physical layout only), or file: the EATG table in eatg_file (one learned beforehand, e.g. an "
        "earlier run's tables/findinghumo_eatg.parquet on a training log)",
        choices=("trained", "layout", "file"),
    )
    eatg_file: str = param(
        "",
        'the .parquet / .csv EATG table read with eatg = "file" (kind, src, dst, weight; a path relative '
        "to the working directory)",
    )
    decoding: str = param(
        "batch",
        "batch -- the whole run at once: windows and the post-processing (joint re-decoding, CPDA) see the "
        "whole log -- or lagged, the paper's live requirement (section III: q_i(t) known by t + D'T): the run "
        "is decoded in blocks of tau slots in time order and a block is final (never revised) once the slots "
        "up to decision_lag after it have arrived; the post-processing of a block looks back c_windows d_max "
        "slots (the committed output) and ahead to that lag (onebit.trackers.findinghumo.lagged). Needs an "
        "EATG known beforehand (layout or file); onebit follow publishes exactly what this gives",
        choices=DECODINGS,
    )
    decision_lag: int = param(
        20,
        "D': a block is decided once decision_lag slots after it have arrived (the paper gives no value; at "
        "least d_max + the decoder's re-entry window of 10 slots)",
        lo=("d_max", RESUME_SLOTS),
        hi=100_000,
        unit="slots",
    )
    lag_lookback: int = param(
        20,
        "slots of committed output the post-processing of a lagged block sees before it (CPDA's last "
        "C d_max slots at least; a meeting re-decoded jointly needs its start: on the hallway demo 10 slots "
        "lost the joint re-decoding's gain, 20 kept it)",
        lo=1,
        hi=100_000,
        unit="slots",
    )
    stay: float = param(0.6, "layout prior probability of staying at a node for one slot", lo=0.0, hi=0.999)
    turn_back: float = param(0.05, "layout prior probability of turning back after one hop", lo=0.0, hi=1.0)
    prior_strength: float = param(2.0, "pseudo-counts of the layout prior per row of the trained EATG", lo=0.0)
    p_hit: float = param(0.9, "probability that the node a user is at is seen active in a slot", lo=0.5, hi=0.999)
    p_false: float = param(0.05, "probability that a node nobody is at is seen active in a slot", lo=1e-6, hi=0.5)
    sweeps: int = param(3, "explain-away sweeps over the users per window (coordinate ascent)", lo=1, hi=20)
    restarts: int = param(
        6,
        "coordinate-ascent runs per window over different user decoding orders (every order when "
        "K! <= restarts, else rotations); the highest joint log-likelihood is kept",
        lo=1,
        hi=20,
    )
    offline: bool = param(False, "decode the whole run as one window (the paper's offline baselines)")
    absent_after: float = param(
        ABSENT_AFTER_S,
        "the empty room: no track row inside a stretch this long in which every sensor is off and nothing "
        "fires (nobody present); 0 = users stay where they were",
        lo=0.0,
        hi=1e12,
        unit="s",
    )
    max_users: int = param(
        0,
        "the most users at once; 0 = the site's targets (the most people present at once), no bound when the "
        "site does not say. It bounds the decoder itself (a window never decodes more users) and the output "
        "(cap_users, which then has nothing left to cut)",
        lo=0,
        hi=10_000,
    )
    count: str = param(
        "fresh",
        "what K_now counts (onebit.models.graph_hmm.adaptive, item 1): fresh -- nodes that turned on in the "
        "last fresh_slots slots -- or on -- every node on (the paper's literal reading; lingering sensors "
        "become users)",
        choices=("fresh", "on"),
    )
    fresh_slots: int = param(2, "slots an onset counts as fresh for K_now", lo=1, hi=1000, unit="slots")
    joint: str = param(
        "off",
        "re-decode every meeting of two users jointly (beyond the paper, onebit.models.graph_hmm.joint); off, "
        "before-cpda (on the HMM's output, what CPDA then starts from) or after-cpda. The baselines hmm1 / "
        "hmm2 default to off (the paper's full-state HMMs as it describes them)",
        choices=JOINT,
    )
    joint_pad: int = param(
        4, "slots a joint re-decoding window extends either side of a meeting", lo=0, hi=100, unit="slots"
    )
    joint_hops: int = param(
        0,
        "0: a meeting is re-decoded on the nodes its two users can reach in the window (exact; "
        "onebit.models.graph_hmm.joint.JointSpaces); r > 0: also only within r hops of their motion (the "
        "paper's state set for overlapping motion, Sec. III-B2 (a), 2 hops) -- faster on long meetings, "
        "approximate",
        lo=0,
        hi=1000,
    )

    def __post_init__(self) -> None:
        validate(self)
        if self.eatg == "file" and not self.eatg_file:
            raise ConfigError(f"{type(self).__name__}.eatg_file is empty; eatg = 'file' reads the EATG table it names")
        if self.decoding == "lagged" and self.eatg == "trained":
            raise ConfigError(
                f"{type(self).__name__}.eatg = 'trained' with decoding = 'lagged': a live decoder cannot learn the "
                "EATG from the whole log; use eatg = 'layout' or 'file' (a graph learned beforehand)"
            )
        if self.decoding == "lagged" and self.offline:
            raise ConfigError(
                f"{type(self).__name__}.offline = True with decoding = 'lagged': offline is one window over the whole run"
            )
