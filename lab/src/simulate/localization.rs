//! Finding itself, scored against the truth (issue #27): the localizer's
//! modes cycle by cycle, the first convergence, hand-offs right and wrong,
//! kidnaps detected and recovered, cycles far off and what the localizer
//! said of them, and whether its covariance holds the true error; and the
//! per-cycle trace a user checks with their own tools (`--trace`).

use serde_json::{json, Value};

use super::filters::{CycleRow, PlaceRow, Trace};
use super::world::wrap;
use echoloc::localize::Mode;

/// An estimate this far off is *off* (m).
pub const OFF_M: f64 = 0.5;
/// Converged: within this distance (m) ...
pub const CONVERGED_M: f64 = 0.3;
/// ... and this angle (degrees) of the truth, while tracking.
pub const CONVERGED_DEG: f64 = 10.0;
/// χ² with 2 degrees of freedom at 99 %: the position's 99 % ellipse.
pub const CHI2_2_99: f64 = 9.210_340_371_976_184;

/// A pose's errors against the truth `t`: position m, heading degrees.
fn pose_error(p: &[f32; 3], t: &[f64; 3]) -> (f64, f64) {
    let e = [f64::from(p[0]) - t[0], f64::from(p[1]) - t[1], wrap(f64::from(p[2]) - t[2])];
    (e[0].hypot(e[1]), e[2].to_degrees().abs())
}

/// A row's errors against its truth: position m, heading degrees.
fn error(r: &CycleRow) -> Option<(f64, f64)> {
    Some(pose_error(&r.state, &r.truth?))
}

/// Whether the true position lies inside the row's 99 % position ellipse.
fn inside_99(r: &CycleRow) -> Option<bool> {
    let t = r.truth?;
    let (dx, dy) = (t[0] - f64::from(r.state[0]), t[1] - f64::from(r.state[1]));
    let p = r.covariance;
    let (a, b, d) = (f64::from(p[0][0]), f64::from(p[0][1]), f64::from(p[1][1]));
    let det = a * d - b * b;
    if det.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
        return Some(false);
    }
    let m = (d * dx * dx - 2.0 * b * dx * dy + a * dy * dy) / det;
    Some(m <= CHI2_2_99)
}

fn round4(v: f64) -> f64 {
    (v * 1e4).round() / 1e4
}

fn converged(r: &CycleRow) -> bool {
    r.mode == Mode::Tracking && error(r).is_some_and(|(p, h)| p <= CONVERGED_M && h <= CONVERGED_DEG)
}

/// The places the cycle before row `i` (at that cycle's end; the truth at
/// its last firing): the living place nearest the truth and the one that
/// leads (the largest smallest lead), each with how far off it is, its
/// position's larger σ, its smallest lead over the null and every other
/// and its evidence; null without the place test's places or a truth.
fn places_before(t: &Trace, i: usize) -> Value {
    let Some(b) = i.checked_sub(1) else { return Value::Null };
    let places = t.cycle_places.iter().rev().find(|(c, _)| *c == b).map(|(_, p)| p);
    let (Some(places), Some(truth)) = (places, t.cycles.get(b).and_then(|r| r.truth)) else {
        return Value::Null;
    };
    let off = |p: &[f32; 3]| pose_error(p, &truth);
    let say = |p: &PlaceRow| {
        let (m, deg) = off(&p.pose);
        // The larger eigenvalue of the position covariance [[a, b], [b, d]].
        let [a, b, d] = p.covariance.map(f64::from);
        let big = 0.5 * (a + d) + (0.25 * (a - d) * (a - d) + b * b).sqrt();
        json!({
            "error_m": round4(m),
            "heading_deg": round4(deg),
            "sigma_m": round4(big.max(0.0).sqrt()),
            "margin_nats": round4(f64::from(p.margin)),
            "evidence_nats": round4(f64::from(p.evidence)),
        })
    };
    let nearest = places.iter().min_by(|a, c| off(&a.pose).0.total_cmp(&off(&c.pose).0));
    let leader = places.iter().max_by(|a, c| a.margin.total_cmp(&c.margin));
    match (nearest, leader) {
        (Some(n), Some(l)) => json!({"cycle": b, "nearest": say(n), "leader": say(l)}),
        _ => Value::Null,
    }
}

/// The `localization` object of the JSON report; `kidnaps` are the
/// simulator's (time s), none for a log.
pub fn report(t: &Trace, kidnaps: &[f64]) -> Value {
    let rows = &t.cycles;
    let n = rows.len();
    let count = |m: Mode| rows.iter().filter(|r| r.mode == m).count();
    let start_time = t.times.first().copied().unwrap_or(0.0);
    let first = rows.iter().find(|r| converged(r));
    // The hand-offs with their rows' indices (the places before them).
    let handoffs: Vec<(usize, &CycleRow)> = rows.iter().enumerate().filter(|(_, r)| r.handoff).collect();
    let wrong: Vec<Value> = handoffs
        .iter()
        .filter_map(|&(_, r)| {
            error(r).filter(|e| e.0 > OFF_M).map(|e| json!({"time_s": round4(r.time_s), "error_m": round4(e.0)}))
        })
        .collect();
    // What the search knew when it handed off: the places alive and the
    // lead it handed off on (with the place test, the winner's smallest
    // lead over the null and every other), and how far off it was.
    // And the places the cycle before, the one nearest the truth and the
    // leader: a wrong hand-off with the truth's place alive and trailing is
    // the measurement model's doing; with none near it, the proposals'.
    let standing: Vec<Value> = handoffs
        .iter()
        .map(|&(i, r)| {
            json!({
                "time_s": round4(r.time_s),
                "distance_m": round4(r.distance_m),
                "places_alive": r.hypotheses,
                "lead_nats": round4(f64::from(r.lead)),
                "error_m": error(r).map(|e| round4(e.0)),
                "places_before": places_before(t, i),
            })
        })
        .collect();
    let known: Vec<(&CycleRow, (f64, f64))> = rows.iter().filter_map(|r| error(r).map(|e| (r, e))).collect();
    let off: Vec<&CycleRow> = known.iter().filter(|(_, e)| e.0 > OFF_M).map(|(r, _)| *r).collect();
    let off_known = off.iter().filter(|r| r.mode != Mode::Tracking).count();
    let tracking: Vec<bool> = rows.iter().filter(|r| r.mode == Mode::Tracking).filter_map(inside_99).collect();
    let consistent = tracking.iter().filter(|&&b| b).count();
    let kid: Vec<Value> = kidnaps
        .iter()
        .map(|&k| {
            let after: Vec<&CycleRow> = rows.iter().filter(|r| r.time_s >= k).collect();
            let detected = after.iter().find(|r| r.mode != Mode::Tracking).map(|r| r.time_s - k);
            let d0 = after.first().map_or(0.0, |r| r.distance_m);
            let recovered = detected.and_then(|dt| {
                after
                    .iter()
                    .filter(|r| r.time_s >= k + dt)
                    .find(|r| converged(r))
                    .map(|r| (r.time_s - k, r.distance_m - d0))
            });
            json!({
                "time_s": k,
                "detected_after_s": detected.map(round4),
                "recovered_after_s": recovered.map(|r| round4(r.0)),
                "recovered_after_m": recovered.map(|r| round4(r.1)),
            })
        })
        .collect();
    let last = rows.last();
    let mode_changes = t.modes.windows(2).filter(|w| w[0] != w[1]).count();
    json!({
        "cycles": n,
        "mode_changes": mode_changes,
        "modes": {"searching": count(Mode::Searching), "tracking": count(Mode::Tracking), "lost": count(Mode::Lost)},
        "first_convergence": first.map(|r| json!({
            "time_s": round4(r.time_s - start_time),
            "distance_m": round4(r.distance_m),
        })),
        "hypotheses_alive": {
            "max": rows.iter().map(|r| r.hypotheses).max().unwrap_or(0),
            "final": last.map_or(0, |r| r.hypotheses),
            "cycles_searching_with_more_than_one": rows.iter().filter(|r| r.mode == Mode::Searching && r.hypotheses > 1).count(),
        },
        "handoffs": handoffs.len(),
        "handoff_standing": standing,
        "wrong_handoffs": wrong,
        "wakes": t.localizer.wakes,
        "takeovers": t.localizer.takeovers,
        "off_fraction": if known.is_empty() { Value::Null } else { json!(round4(off.len() as f64 / known.len() as f64)) },
        "off_cycles": off.len(),
        "off_cycles_known": if off.is_empty() { Value::Null } else { json!(round4(off_known as f64 / off.len() as f64)) },
        "tracking_inside_99": if tracking.is_empty() { Value::Null } else { json!(round4(consistent as f64 / tracking.len() as f64)) },
        "kidnaps": kid,
        "final_mode": last.map(|r| r.mode.name()),
        "final_error_m": last.and_then(error).map(|e| round4(e.0)),
        "ended_off": last.and_then(error).map(|e| e.0 > OFF_M),
    })
}

/// The per-cycle trace as CSV (issue #27's header): the mode, the estimate
/// and its σ, the reference where known, and while searching or lost the
/// heaviest cluster's lead over the best place elsewhere and its weight
/// (what the hand-off waits for); with the place test, how far the EKF's
/// pose trails the null (`behind_nats`, *lost* at the bound; 0 without
/// the test).
pub fn trace_csv(t: &Trace) -> String {
    let mut out = String::from(
        "time_s,mode,x_m,y_m,theta_rad,sigma_x_m,sigma_y_m,sigma_theta_rad,ref_x_m,ref_y_m,ref_theta_rad,particles,lead_nats,cluster_weight,behind_nats\n",
    );
    for r in &t.cycles {
        let p = r.covariance;
        let sd = |i: usize| f64::from(p[i][i]).max(0.0).sqrt();
        // What the hand-off waits for, while the particles search; while
        // tracking with rivals, the best place's lead (the takeover's).
        let (lead, weight) = if r.mode == Mode::Tracking && r.hypotheses == 0 {
            (String::new(), String::new())
        } else {
            (format!("{:.1}", r.lead), format!("{:.3}", r.cluster_weight))
        };
        let (rx, ry, rt) = match r.truth {
            Some(t) => (format!("{:.6}", t[0]), format!("{:.6}", t[1]), format!("{:.6}", t[2])),
            None => (String::new(), String::new(), String::new()),
        };
        out.push_str(&format!(
            "{:.6},{},{:.6},{:.6},{:.6},{:.6},{:.6},{:.6},{rx},{ry},{rt},{},{lead},{weight},{:.1}\n",
            r.time_s,
            r.mode.name(),
            r.state[0],
            r.state[1],
            r.state[2],
            sd(0),
            sd(1),
            sd(2),
            r.held,
            r.behind,
        ));
    }
    out
}

/// What `--start` / `--initial-pose` said.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum StartArg {
    /// `unknown`.
    Unknown,
    /// `x_m,y_m,θ_deg`: tracked from there (m, m, rad).
    At([f64; 3]),
    /// `x_m,y_m,θ_deg,σ_m,σ_deg`: searched around it (m, m, rad; σ m, rad).
    Around([f64; 3], [f64; 2]),
}

/// Parses `unknown`, `x_m,y_m,θ_deg` or `x_m,y_m,θ_deg,σ_m,σ_deg`; `what`
/// names the option in errors.
pub fn parse_start(s: &str, what: &str) -> Result<StartArg, String> {
    if s.trim().eq_ignore_ascii_case("unknown") {
        return Ok(StartArg::Unknown);
    }
    let v: Result<Vec<f64>, _> = s.split(',').map(|t| t.trim().parse::<f64>()).collect();
    let v = v.map_err(|_| format!("{what} {s:?}: expected unknown, x_m,y_m,θ_deg or x_m,y_m,θ_deg,σ_m,σ_deg"))?;
    if !v.iter().all(|x| x.is_finite()) {
        return Err(format!("{what} {s:?}: numbers must be finite"));
    }
    let pose = |v: &[f64]| -> Result<[f64; 3], String> {
        if v[0].abs() > 1e6 || v[1].abs() > 1e6 || v[2].abs() > 1e6 {
            return Err(format!("{what} {s:?}: positions within ±1000 km, headings within ±1000000°"));
        }
        Ok([v[0], v[1], v[2].to_radians()])
    };
    match v.len() {
        3 => Ok(StartArg::At(pose(&v)?)),
        5 if v[3] > 0.0 && v[4] > 0.0 && v[3] <= 1e3 && v[4] <= 360.0 => {
            Ok(StartArg::Around(pose(&v)?, [v[3], v[4].to_radians()]))
        }
        5 => Err(format!("{what} {s:?}: σ_m must be within (0, 1000] and σ_deg within (0, 360]")),
        _ => Err(format!("{what} {s:?}: expected unknown, x_m,y_m,θ_deg or x_m,y_m,θ_deg,σ_m,σ_deg")),
    }
}

/// Parses `--kidnap T_s:dx_m,dy_m,dθ_deg`.
pub fn parse_kidnap(s: &str) -> Result<super::world::Kidnap, String> {
    let bad = || format!("--kidnap {s:?}: expected T_s:dx_m,dy_m,dθ_deg");
    let (t, d) = s.split_once(':').ok_or_else(bad)?;
    let t: f64 = t.trim().parse().map_err(|_| bad())?;
    let v: Result<Vec<f64>, _> = d.split(',').map(|x| x.trim().parse::<f64>()).collect();
    let v = v.map_err(|_| bad())?;
    match v[..] {
        [dx, dy, dth] if t.is_finite() && t > 0.0 && [dx, dy, dth].iter().all(|x| x.is_finite() && x.abs() <= 1e6) => {
            Ok(super::world::Kidnap { t_s: t, dx_m: dx, dy_m: dy, dtheta_rad: dth.to_radians() })
        }
        [_, _, _] => Err(format!("--kidnap {s:?}: T_s must be after 0, every number finite")),
        _ => Err(bad()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(handoff: bool, truth: Option<[f64; 3]>) -> CycleRow {
        CycleRow {
            time_s: 0.0,
            mode: if handoff { Mode::Tracking } else { Mode::Searching },
            state: [0.0; 3],
            covariance: [[0.0; 3]; 3],
            truth,
            handoff,
            woke: false,
            calmed: false,
            particles: 0,
            held: 0,
            lead: 0.0,
            behind: 0.0,
            cluster: None,
            rival: None,
            hypotheses: 2,
            cluster_weight: 0.0,
            distance_m: 0.0,
        }
    }

    fn place(pose: [f32; 3], margin: f32) -> PlaceRow {
        PlaceRow { pose, covariance: [0.01, 0.0, 0.01], evidence: margin + 1.0, margin, cycles: 3 }
    }

    /// The places the cycle before a hand-off, by hand: the truth's place
    /// 0.5 m off (a 3-4-5 triangle), 0.1 rad (5.7296°) turned, σ 0.3 m
    /// along its larger axis (covariance [[0.05, 0.04], [0.04, 0.05]]:
    /// eigenvalues 0.09 and 0.01), trailing by 5 nats, while a place 12 m
    /// away leads by 160.
    #[test]
    fn a_hand_off_says_where_the_truths_place_stood() {
        let mut near = place([1.3, 2.4, 0.1], -5.0);
        near.covariance = [0.05, 0.04, 0.05];
        let mut t = Trace {
            cycles: vec![row(false, Some([1.0, 2.0, 0.0])), row(true, Some([1.1, 2.0, 0.0]))],
            cycle_places: vec![(0, vec![place([13.0, 2.0, 0.0], 160.0), near])],
            ..Trace::default()
        };
        let v = places_before(&t, 1);
        assert_eq!(v["cycle"], 0);
        let n = &v["nearest"];
        assert_eq!((&n["error_m"], &n["heading_deg"], &n["sigma_m"]), (&json!(0.5), &json!(5.7296), &json!(0.3)));
        assert_eq!((&n["margin_nats"], &n["evidence_nats"]), (&json!(-5.0), &json!(-4.0)));
        let l = &v["leader"];
        assert_eq!((&l["error_m"], &l["heading_deg"], &l["sigma_m"]), (&json!(12.0), &json!(0.0), &json!(0.1)));
        assert_eq!(l["margin_nats"], 160.0);
        // No places the cycle before (the first cycle, or places only on an
        // earlier one), or no truth: nothing to say.
        assert_eq!(places_before(&t, 0), Value::Null);
        t.cycle_places[0].0 = 5;
        assert_eq!(places_before(&t, 1), Value::Null);
        t.cycle_places[0].0 = 0;
        t.cycles[0].truth = None;
        assert_eq!(places_before(&t, 1), Value::Null);
    }
}
