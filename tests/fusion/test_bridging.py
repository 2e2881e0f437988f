"""fusion.bridging (the bridging strategies) and the virtual-outage machinery they use
(fusion.bridging.virtual_outages.VirtualOutageBank inside NavFilter)."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterable
from typing import Any

import numpy as np
import pytest
from pydantic import ValidationError

from fusion import earth
from fusion.bridging.features import (
    base_row,
    compile_features,
    feature_spec,
    features_matrix,
    features_row,
)
from fusion.bridging.interface import (
    BridgeEpoch,
    BridgeStatus,
    InsError,
    NoBridge,
    OutputCorrection,
    PseudoGnss,
    VirtualOutage,
)
from fusion.bridging.learned import LearnedBridge
from fusion.bridging.registry import BRIDGE_METHODS, make_bridge
from fusion.bridging.virtual_outages import VirtualOutageBank
from fusion.config import BRIDGE_FEATURES, BridgeConfig, FilterConfig, GnssTuning
from fusion.estimate import NavEstimate
from fusion.filter import NavFilter
from fusion.strapdown import InsState
from sim.samples import ImuSample
from tests.helpers.nav_synth import Flight, Prepared, SensorErrors, make_scenario, prepare

CFG = FilterConfig()
ERRORS = SensorErrors.from_config(CFG)
# Small windows so a 70 s synthetic flight trains every method before its outage.
FAST = BridgeConfig(
    virtual_outage_s=20.0, virtual_outage_count=2, warmup_s=5.0, min_horizon_s=5.0,
    min_samples=30, refit_period_s=3.0, window_s=60.0, max_samples=300, mlp_max_nfev=3,
    mlp_max_samples=80, mlp_hidden=35, bp_epochs=60,
)  # fmt: skip


@pytest.fixture(scope="module")
def turning() -> Prepared:
    """70 s: straight, turns both ways, a climb (every feature moves)."""
    return prepare(
        Flight(
            duration_s=70.0,
            turns=[(8.0, 20.0, 0.15), (28.0, 40.0, -0.15), (52.0, 64.0, 0.12)],
            climbs=[(20.0, 28.0, 2.0)],
        )
    )


def run(nav: NavFilter, samples: Iterable[Any]) -> list[NavEstimate]:
    out: list[NavEstimate] = []
    for s in samples:
        out.extend(nav.step(s))
    return out


# --------------------------------------------------------------------------- construction
def test_every_method_constructs_by_name_and_unknown_names_list_them() -> None:
    for name in BRIDGE_METHODS:
        bridge = make_bridge(name)
        assert bridge.name == name
    assert isinstance(make_bridge("none"), NoBridge)
    with pytest.raises(ValueError, match="valid methods: none, gmdh, gmdh-pseudo, mlp, rbf"):
        make_bridge("kalman")


def test_method_defaults_fill_only_what_the_caller_left_unset() -> None:
    slow = make_bridge("mlp")
    assert isinstance(slow, LearnedBridge) and slow.config.refit_period_s == 20.0
    mine = make_bridge("mlp", BridgeConfig(refit_period_s=5.0))
    assert isinstance(mine, LearnedBridge) and mine.config.refit_period_s == 5.0
    plain = make_bridge("gmdh", BridgeConfig())
    assert isinstance(plain, LearnedBridge) and plain.config.refit_period_s == 10.0


def test_bridge_config_rejects_unknown_features_naming_them() -> None:
    with pytest.raises(ValidationError, match="unknown features \\['heading'\\]"):
        BridgeConfig(features=("t", "heading"))
    with pytest.raises(ValidationError, match="training"):
        BridgeConfig(training="offline")  # type: ignore[arg-type]


def test_none_reports_off_and_costs_no_virtual_outages() -> None:
    nav = NavFilter(CFG)
    assert nav.bridge_status == BridgeStatus("none", "off")
    assert nav.virtual_outage_states == []


# --------------------------------------------------------------------------- features
def _epoch(t_s: float, yaw: float = 0.3, n_m: float = 0.0, el: float = 0.0) -> BridgeEpoch:
    lat0, lon0 = math.radians(47.0), math.radians(8.0)
    lt = earth.local_terms(lat0, 500.0)
    return BridgeEpoch(
        round(t_s * 1e6), lat0 + n_m / lt.rho_n_m, lon0, 500.0,
        (40.0 * math.cos(yaw), 40.0 * math.sin(yaw), -1.0), (0.1, 0.05, yaw),
        (0.5, -0.3, -9.7), (0.01, 0.0, 0.1), el, (1e-3, 2e-3, -1e-3), (1e-5, -2e-5, 3e-5),
    )  # fmt: skip


def test_feature_paths_agree_row_matrix_and_compiled() -> None:
    start, now = _epoch(0.0, 0.1), _epoch(12.0, 1.2, n_m=300.0, el=12.0)
    from fusion.bridging.features import Origin

    base = base_row(12.0, start, now, Origin(start))
    for k in range(6):
        spec = feature_spec(BRIDGE_FEATURES, k)
        row = features_row(base, spec)
        mat = features_matrix(np.array([base]), spec)[0]
        np.testing.assert_allclose(row, mat, rtol=1e-15)
        wide = compile_features(spec, [-1e9] * len(spec), [1e9] * len(spec))(base)
        assert wide == row
        # clipping to the training range
        clip = compile_features(spec, [0.0] * len(spec), [1.0] * len(spec))(base)
        assert clip == [min(max(x, 0.0), 1.0) for x in row]
    t, dn = features_row(base, feature_spec(("t", "dn"), 0))
    assert t == 12.0 and dn == pytest.approx(300.0, abs=1e-6)
    with pytest.raises(ValueError, match="unknown feature 'x'"):
        feature_spec(("x",), 0)


# --------------------------------------------------------------------------- learning
def _drift_stream(
    law: dict[str, float], n_outages: int = 12, seed: int = 0, length_s: float = 40.0
) -> list[tuple[BridgeEpoch, InsError]]:
    """Virtual outages of ``length_s`` at 5 Hz, one heading each (random), three overlapping:
    error N/E = a t^2 (cos, sin) of the heading, noise 0.2 m."""
    rng = np.random.default_rng(seed)
    a = law["a"]
    out = []
    starts = []
    for w in range(n_outages):
        yaw = float(rng.uniform(-math.pi, math.pi))
        starts.append((w * 15.0, yaw))
    t_end = n_outages * 15.0 + length_s
    for i in range(int(t_end * 5)):
        t = i * 0.2
        virt = []
        for j, (t0, yaw) in enumerate(starts):
            el = t - t0
            if not 0.0 < el <= length_s:
                continue
            start = _epoch(t0, yaw)
            ep = _epoch(t, yaw, n_m=40.0 * el * math.cos(yaw), el=el)
            e = a * el * el
            noise = rng.normal(0.0, 0.2, 2)
            virt.append(VirtualOutage(
                j % 3, el, start, ep,
                (e * math.cos(yaw) + noise[0], e * math.sin(yaw) + noise[1], 0.0),
                (2 * a * el * math.cos(yaw), 2 * a * el * math.sin(yaw), 0.0),
            ))  # fmt: skip
        out.append((_epoch(t, 0.0), InsError(_Z3, _Z3, True, True, tuple(virt))))
    return out


_Z3 = (0.0, 0.0, 0.0)


def test_gmdh_learns_a_drift_law_rotated_by_heading_from_virtual_outages() -> None:
    # GIVEN virtual outages whose error is 0.02 t^2 along the heading (plus 0.2 m noise)
    cfg = BridgeConfig(features=("t", "t2", "sinpsi", "cospsi"), warmup_s=0.0,
                       min_horizon_s=10.0, window_s=1000.0, refit_period_s=5.0)  # fmt: skip
    bridge = make_bridge("gmdh", cfg)
    assert isinstance(bridge, LearnedBridge)
    stream = _drift_stream({"a": 0.02})
    for ep, err in stream:
        bridge.on_gnss(ep, err)
    st = bridge.status
    assert st.state == "trained" and not any(st.fallback[k] for k in (0, 1, 3, 4))
    # WHEN it predicts outages at headings and times it has not seen
    last = stream[-1][0]
    got, want = [], []
    for yaw in (0.7, -2.0, 2.9):
        for el in (5.0, 15.0, 25.0, 35.0):
            bridge.on_gnss(_epoch(last.time_us * 1e-6, yaw), InsError(_Z3, _Z3, True, True))
            t = last.time_us * 1e-6 + el
            act = bridge.on_outage(_epoch(t, yaw, n_m=40.0 * el * math.cos(yaw), el=el))
            assert isinstance(act, OutputCorrection)
            got.append(act.pos_ned_m[:2])
            want.append((0.02 * el * el * math.cos(yaw), 0.02 * el * el * math.sin(yaw)))
            # GNSS back: its first fix shows the drift the law predicts (the gate scores it)
            v = 0.04 * el
            bridge.on_gnss(_epoch(t, yaw), InsError(
                (want[-1][0], want[-1][1], 0.0), (v * math.cos(yaw), v * math.sin(yaw), 0.0),
                True, True))  # fmt: skip
            bridge.on_gnss_restored(_epoch(t, yaw))
    # THEN the prediction follows the law (measured: 0.1 % relative RMS error)
    got_a, want_a = np.array(got), np.array(want)
    rel = np.sqrt(np.mean((got_a - want_a) ** 2)) / np.sqrt(np.mean(want_a**2))
    assert rel < 0.1, f"relative RMS error {rel:.3f}"


def _shifted(stream: list[tuple[BridgeEpoch, InsError]], dt_s: float) -> list[
    tuple[BridgeEpoch, InsError]
]:  # fmt: skip
    """The same stream ``dt_s`` later."""
    d = round(dt_s * 1e6)

    def ep(e: BridgeEpoch) -> BridgeEpoch:
        return dataclasses.replace(e, time_us=e.time_us + d)

    return [
        (ep(e), dataclasses.replace(err, virtual=tuple(
            dataclasses.replace(v, start=ep(v.start), epoch=ep(v.epoch))
            for v in err.virtual)))
        for e, err in stream
    ]  # fmt: skip


GATE_CFG = BridgeConfig(features=("t", "t2", "sinpsi", "cospsi"), warmup_s=0.0,
                        min_horizon_s=10.0, window_s=1000.0, refit_period_s=6.0,
                        max_samples=600)  # fmt: skip


def test_gate_keeps_a_model_that_cannot_predict_off_and_the_output_is_none() -> None:
    # GIVEN a drift along a random heading per outage, and inputs without the heading: the
    # fitted model predicts some mean drift that no single outage has
    bridge = make_bridge("gmdh", GATE_CFG.model_copy(update={"features": ("t", "t2")}))
    assert isinstance(bridge, LearnedBridge)
    for ep, err in _drift_stream({"a": 0.02}):
        bridge.on_gnss(ep, err)
    st = bridge.status
    # THEN the networks are fitted, but the held-out virtual outages show the correction does
    # not beat no correction by the margin, and the strategy does what `none` does
    assert st.state == "trained" and st.refits > 10
    assert all(st.fallback)
    for k in (0, 1):
        assert st.validation_rmse[k] > GATE_CFG.gate_margin * st.zero_rmse[k]
    assert bridge.on_outage(_epoch(230.0, el=20.0)) is None
    assert NoBridge().on_outage(_epoch(230.0, el=20.0)) is None
    assert not bridge.status.active


def test_gate_turns_on_for_a_learnable_drift_and_off_when_it_stops_winning() -> None:
    # GIVEN the learnable law (0.02 t^2 along the heading): the gate lets it through
    bridge = make_bridge("gmdh", GATE_CFG)
    assert isinstance(bridge, LearnedBridge)
    first = _drift_stream({"a": 0.02})
    for ep, err in first:
        bridge.on_gnss(ep, err)
    st = bridge.status
    assert not any(st.fallback[k] for k in (0, 1))
    assert st.validation_rmse[0] < 0.2 * st.zero_rmse[0]
    assert isinstance(bridge.on_outage(_epoch(230.0, el=20.0)), OutputCorrection)
    bridge.on_gnss_restored(_epoch(230.0))
    # WHEN the aircraft's drift reverses (a new error source the window has not seen)
    off_at = None
    t_last = first[-1][0].time_us * 1e-6
    for i, (ep, err) in enumerate(_shifted(_drift_stream({"a": -0.02}, seed=1), t_last + 0.2)):
        bridge.on_gnss(ep, err)
        if off_at is None and all(bridge.status.fallback[k] for k in (0, 1)):
            off_at = i * 0.2
    # THEN the first outage it loses turns it off, long before the window forgets the old law
    assert off_at is not None and off_at < 60.0, off_at


@pytest.mark.parametrize("accepted", [True, False], ids=["fix-accepted", "fix-refused"])
def test_gate_scores_a_real_outage_by_the_first_fix_after_it(accepted: bool) -> None:
    # GIVEN a trained, enabled bridge
    bridge = make_bridge("gmdh", GATE_CFG.model_copy(update={"gate_min_wins": 1.0}))
    stream = _drift_stream({"a": 0.02})
    for ep, err in stream:
        bridge.on_gnss(ep, err)
    assert not bridge.status.fallback[0]  # type: ignore[attr-defined]
    # WHEN a real outage ends and GNSS shows the correction was wrong (no drift at all),
    # whether or not the filter's gate took that first fix (after a long outage it may refuse
    # good fixes for seconds: the outages a bad correction causes must still be judged)
    t = stream[-1][0].time_us * 1e-6 + 20.0
    act = bridge.on_outage(_epoch(t, el=20.0))
    assert isinstance(act, OutputCorrection) and abs(act.pos_ned_m[0]) > 1.0
    bridge.on_gnss(_epoch(t + 0.2), InsError(_Z3, _Z3, accepted, accepted))
    bridge.on_gnss_restored(_epoch(t + 0.2))
    # THEN the components it made worse are off (the most recent outage must be a win)
    assert bridge.status.fallback[0]  # type: ignore[attr-defined]


def test_a_virtual_outage_running_past_the_gate_horizon_is_scored_once() -> None:
    # GIVEN virtual-outage INS copies that keep drifting 30 s past the gate's 60 s scoring horizon
    cfg = GATE_CFG.model_copy(update={"gate_outages": 100})
    bridge = make_bridge("gmdh", cfg)
    assert isinstance(bridge, LearnedBridge)
    n = 6
    for ep, err in _drift_stream({"a": 0.02}, n_outages=n, length_s=90.0):
        bridge.on_gnss(ep, err)
    # THEN each is scored once, by the models of its start (never again on every later fix,
    # by models that have trained on it)
    for k in (0, 1):
        assert 0 < len(bridge._gate.scores[k]) <= n


def test_a_correction_never_exceeds_the_drift_seen_at_that_stage_of_training() -> None:
    # GIVEN a bridge trained on outages that drift at most 0.02 * 40^2 = 32 m in 40 s
    bridge = make_bridge("gmdh", GATE_CFG)
    assert isinstance(bridge, LearnedBridge)
    for ep, err in _drift_stream({"a": 0.02}):
        bridge.on_gnss(ep, err)
    # THEN 5 s into an outage no prediction exceeds 1.5 x the largest error seen by
    # 1.25 * 5 + 2 s of training outages (0.02 * 8.25^2 = 1.4 m plus noise)
    pred = bridge._predict(_epoch(300.0, el=5.0))
    assert pred is not None
    assert all(abs(p) <= 1.5 * (0.02 * 8.25**2 + 1.0) for p in pred[:2] if math.isfinite(p))


def test_mlp_refits_are_bounded_and_continue_training_across_refits() -> None:
    cfg = GATE_CFG.model_copy(update={"mlp_max_nfev": 3, "mlp_max_samples": 120,
                                      "refit_period_s": 8.0, "mlp_hidden": 10})  # fmt: skip
    bridge = make_bridge("mlp", cfg)
    assert isinstance(bridge, LearnedBridge)
    totals = []
    for ep, err in _drift_stream({"a": 0.02}, n_outages=5):
        bridge.on_gnss(ep, err)
        cand = bridge._cand[0]  # the north-position network (white-box: its LM counters)
        if cand is not None:
            narx = cand.model._model  # type: ignore[attr-defined]
            assert narx.n_iter_ <= 3 and bridge.status.last_fit_samples <= 120
            totals.append(narx.n_iter_total_)
    # every refit is bounded, and each continues the previous weights: the evaluation count
    # of the model in use keeps growing past one refit's bound
    assert totals and totals[-1] > 3 * 3
    assert totals == sorted(totals)


def test_refits_are_bounded_one_per_fix_and_by_the_sample_budget() -> None:
    cfg = BridgeConfig(features=("t", "cospsi"), warmup_s=0.0, min_horizon_s=5.0,
                       max_samples=200, refit_period_s=2.0, window_s=1000.0)  # fmt: skip
    bridge = make_bridge("gmdh", cfg)
    fits = []
    for ep, err in _drift_stream({"a": 0.01}, n_outages=6):
        before = bridge.status.refits  # type: ignore[attr-defined]
        bridge.on_gnss(ep, err)
        st = bridge.status  # type: ignore[attr-defined]
        assert st.refits - before <= 1
        if st.refits > before:
            fits.append(st.last_fit_samples)
    assert fits and max(fits) <= 200
    assert bridge.status.samples > 1000  # type: ignore[attr-defined]


def test_status_goes_untrained_training_trained_stale() -> None:
    cfg = BridgeConfig(features=("t", "t2", "sinpsi", "cospsi"), warmup_s=0.0,
                       min_horizon_s=10.0, stale_after_s=30.0, refit_period_s=5.0,
                       window_s=1000.0)  # fmt: skip
    bridge = make_bridge("gmdh", cfg)
    states = []
    stream = _drift_stream({"a": 0.01})
    for ep, err in stream:
        bridge.on_gnss(ep, err)
        states.append(bridge.status.state)  # type: ignore[attr-defined]
    seq = [s for i, s in enumerate(states) if i == 0 or s != states[i - 1]]
    assert seq == ["untrained", "training", "trained"]
    # a long outage: no refit for longer than stale_after_s
    t_end = stream[-1][0].time_us * 1e-6
    bridge.on_outage(_epoch(t_end + 10.0, el=10.0))
    assert bridge.status.state == "trained"  # type: ignore[attr-defined]
    bridge.on_outage(_epoch(t_end + 40.0, el=40.0))
    st = bridge.status  # type: ignore[attr-defined]
    assert st.state == "stale" and st.active


def test_untrained_bridge_behaves_as_none_and_says_so() -> None:
    bridge = make_bridge("gmdh")
    assert bridge.status.state == "untrained"  # type: ignore[attr-defined]
    assert bridge.on_outage(_epoch(1.0, el=1.0)) is None
    assert bridge.status.fallback == (True,) * 6  # type: ignore[attr-defined]


def test_degenerate_pairs_never_crash_and_fall_back() -> None:
    # constant inputs and zero targets: singular normal equations, nothing to learn
    cfg = BridgeConfig(features=("t", "fn", "bax"), warmup_s=0.0, min_horizon_s=0.0,
                       min_samples=20, window_s=1000.0)  # fmt: skip
    for name in ("gmdh", "rbf", "bp-parallel"):
        bridge = make_bridge(name, cfg.model_copy(update={"features": None})
                             if name == "bp-parallel" else cfg)  # fmt: skip
        start = _epoch(0.0)
        for i in range(60):
            v = VirtualOutage(0, 1.0, start, _epoch(1.0, el=1.0), _Z3, _Z3)
            bad = VirtualOutage(1, math.nan, start, start, _Z3, _Z3)  # dropped, not learned
            bridge.on_gnss(_epoch(i * 0.2), InsError(_Z3, _Z3, True, True, (v, bad)))
        st = bridge.status  # type: ignore[attr-defined]
        assert st.refits > 0 and st.samples == 60
        assert all(st.fallback) and bridge.on_outage(_epoch(20.0, el=8.0)) is None


# --------------------------------------------------------------------------- virtual-outage INS
class _Asking(NoBridge):
    """Records the virtual outages it is handed; corrects nothing."""

    name = "asking"
    virtual_outage_s = 2.0
    virtual_outage_count = 2

    def __init__(self) -> None:
        self.virtual: list[VirtualOutage] = []

    def on_gnss(self, epoch: BridgeEpoch, error: InsError) -> None:
        self.virtual.extend(error.virtual)

    def on_outage(self, epoch: BridgeEpoch) -> None:
        return None

    def on_gnss_restored(self, epoch: BridgeEpoch) -> None:
        return None


def test_virtual_outage_ins_equals_the_main_ins_when_no_update_happened(turning: Prepared) -> None:
    # GIVEN a filter started from a known state and only IMU samples (no aiding at all; a long
    # outage timeout keeps it out of outage mode, so the copies keep re-seeding)
    sc = make_scenario(turning, np.random.default_rng(3), ERRORS)
    cfg = CFG.model_copy(update={"gnss": GnssTuning(outage_timeout_s=100.0)})
    nav = NavFilter(cfg, bridge=_Asking())
    kin = sc.traj(np.array([0.0]))
    lat, lon, h = kin.lla[0]
    nav.initialize(0, lat, lon, h, kin.v_ned_mps[0], kin.q_nb[0])
    imu = [s for s in sc.samples if isinstance(s, ImuSample)][:1500]
    seen = 0
    for k, s in enumerate(imu):
        nav.step(s)
        # THEN every seeded copy is bit-for-bit the main INS (staggered re-seeds included)
        if k % 25 == 0:
            for st in nav.virtual_outage_states:
                if st is not None:
                    assert st == nav.ins_state
                    seen += 1
    assert seen > 80 and all(st is not None for st in nav.virtual_outage_states)


def test_virtual_outage_bank_reseeds_staggered_and_holds_one_free_ins_in_an_outage() -> None:
    seeds: list[int] = []

    def epoch_fn(t_us: int, s: InsState) -> BridgeEpoch:
        seeds.append(t_us)
        return _epoch(t_us * 1e-6)

    bank = VirtualOutageBank(1.0, 2, epoch_fn)
    state = InsState(0.8, 0.1, 500.0, (40.0, 0.0, 0.0), (1.0, 0.0, 0.0, 0.0))
    z = (0.0, 0.0, 0.0)
    for i in range(1, 301):  # 3 s at 100 Hz
        bank.step(i * 10_000, state, z, z, 0.01, z, z)
    assert seeds == [10_000, 510_000, 1_010_000, 1_510_000, 2_010_000, 2_510_000]
    bank.begin_outage(3_000_000, state, z, z, z, z)
    assert bank.in_outage and bank.free_state == state and bank.states[1] is None
    assert bank.samples(3_000_000, state, state, z, z) == ()
    bank.end_outage(3_500_000)
    assert not bank.in_outage and bank.free_state is None
    bank.step(3_510_000, state, z, z, 0.01, z, z)
    assert bank.states[0] == state
    bank.restart(3_600_000)  # an IMU gap: every copy dropped, re-seeded from then on
    assert bank.states == [None, None]
    bank.step(3_610_000, state, z, z, 0.01, z, z)
    assert bank.states == [state, None]
    with pytest.raises(ValueError, match="period_s"):
        VirtualOutageBank(0.0, 1, epoch_fn)


def test_virtual_outage_pairs_measure_drift_the_fix_innovations_do_not(
    turning: Prepared,
) -> None:
    # GIVEN a filter fusing GNSS on a turning flight with sensor errors, INS copies re-seeded
    # every 20 s
    sc = make_scenario(turning, np.random.default_rng(4), ERRORS)
    asking = _Asking()
    asking.virtual_outage_s = 20.0
    nav = NavFilter(CFG, bridge=asking)
    fixes: list[float] = []
    orig = asking.on_gnss

    def on_gnss(epoch: BridgeEpoch, error: InsError) -> None:
        fixes.append(float(np.hypot(*error.pos_ned_m[:2])))
        orig(epoch, error)

    asking.on_gnss = on_gnss  # type: ignore[method-assign]
    run(nav, sc.samples)
    late = [v for v in asking.virtual if v.elapsed_s > 15.0 and v.start.time_us > 10e6]
    assert late
    # THEN the closed-loop filter's own INS-minus-GNSS error at a fix (P0's training pairs)
    # stays at the GNSS noise, while a copy left alone for 15-20 s has drifted further
    rms_fix = float(np.sqrt(np.mean(np.square(fixes[250:]))))
    rms_virtual = float(np.sqrt(np.mean([np.hypot(*v.pos_ned_m[:2]) ** 2 for v in late])))
    assert rms_fix < 3.0 and rms_virtual > 1.5 * rms_fix


# --------------------------------------------------------------------------- in the filter
@pytest.mark.parametrize("name", BRIDGE_METHODS)
def test_every_method_runs_in_the_filter_through_an_outage(turning: Prepared, name: str) -> None:
    sc = make_scenario(turning, np.random.default_rng(5), ERRORS, gnss_outages=[(50.0, 62.0)])
    # the NARX MLP's Levenberg-Marquardt fits are slow: fewer of them
    cfg = FAST.model_copy(update={"refit_period_s": 15.0}) if name == "mlp" else FAST
    nav = NavFilter(CFG, bridge=make_bridge(name, cfg))
    est = run(nav, sc.samples)
    assert est and all(np.isfinite(e.lat_rad) and np.all(np.isfinite(e.v_ned_mps)) for e in est)
    during = [e for e in est if 52e6 <= e.time_us <= 61e6]
    st = during[0].bridge
    assert st is not None and st.method == name
    if name == "none":
        assert st.state == "off" and all(e.mode == "free-inertial" for e in during)
        return
    if name in ("gmdh-airspeed", "gmdh-wind", "gmdh-pitot"):
        # they learn from controls and rpm, or the air data: this stream has neither
        # (tests/fusion/test_airspeed.py, test_wind_model.py)
        assert st.state == "no inputs" and all(e.mode == "free-inertial" for e in during)
        return
    if name == "gmdh-thermal":
        # a constant die temperature teaches nothing (tests/fusion/test_thermal.py)
        assert st.state == "untrained" and not st.active
        assert all(e.mode == "free-inertial" for e in during)
        return
    assert st.state in ("trained", "stale") and st.refits >= 4 and st.samples > 30
    active = not all(st.fallback)
    assert all(e.mode == ("bridging" if active else "free-inertial") for e in during[1:])
    assert est[-1].mode == "gnss" and est[-1].bridge is not None
    assert not est[-1].bridge.active


def test_an_outage_right_after_start_is_flown_exactly_as_none(turning: Prepared) -> None:
    # GIVEN GNSS lost 12 s after start (the default warm-up alone is 90 s)
    sc = make_scenario(turning, np.random.default_rng(6), ERRORS, gnss_outages=[(12.0, 30.0)])
    plain = run(NavFilter(CFG), sc.samples)
    learned = run(NavFilter(CFG, bridge=make_bridge("gmdh")), sc.samples)
    # THEN the strategy stays untrained and the output is the plain filter's, bit for bit
    during = [e for e in learned if 14e6 <= e.time_us <= 29e6]
    assert during and all(e.bridge is not None and e.bridge.state == "untrained"
                          and e.mode == "free-inertial" for e in during)  # fmt: skip
    assert len(plain) == len(learned)
    for a, b in zip(plain, learned, strict=True):
        assert (a.lat_rad, a.lon_rad, a.alt_msl_m) == (b.lat_rad, b.lon_rad, b.alt_msl_m)


def test_pseudo_gnss_comes_from_the_free_ins_minus_the_predicted_drift() -> None:
    # GIVEN a trained gmdh-pseudo strategy
    cfg = BridgeConfig(features=("t", "t2", "sinpsi", "cospsi"), warmup_s=0.0,
                       min_horizon_s=10.0, window_s=1000.0)  # fmt: skip
    bridge = make_bridge("gmdh-pseudo", cfg)
    for ep, err in _drift_stream({"a": 0.02}):
        bridge.on_gnss(ep, err)
    # WHEN it is consulted with and without the free-running INS of the outage
    free = InsState(0.82, 0.14, 480.0, (10.0, 20.0, 1.0), (1.0, 0.0, 0.0, 0.0))
    ep = _epoch(200.0, el=20.0)
    from_free = bridge.on_outage(dataclasses.replace(ep, free_state=free))
    from_ins = bridge.on_outage(ep)
    # THEN both are the state minus the same predicted drift (the free INS when there is one:
    # the filter's INS has been moved by earlier pseudo-fixes)
    assert isinstance(from_free, PseudoGnss) and isinstance(from_ins, PseudoGnss)
    lt_f = earth.local_terms(free.lat_rad, free.alt_msl_m)
    lt_i = earth.local_terms(ep.lat_rad, ep.alt_msl_m)
    drift_f = (free.lat_rad - from_free.lat_rad) * lt_f.rho_n_m
    drift_i = (ep.lat_rad - from_ins.lat_rad) * lt_i.rho_n_m
    assert drift_f == pytest.approx(drift_i, rel=1e-6) and abs(drift_i) > 1.0
    for k in range(3):
        assert free.v_ned_mps[k] - from_free.v_ned_mps[k] == pytest.approx(
            ep.v_ned_mps[k] - from_ins.v_ned_mps[k])  # fmt: skip
    assert from_free.sigma_pos_m >= cfg.pseudo_min_sigma_pos_m
    assert from_free.sigma_vel_mps >= cfg.pseudo_min_sigma_vel_mps
