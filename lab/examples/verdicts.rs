//! A small host program over the `echoloc_lab` library: loads a map, predicts
//! a ring at a pose and prints the verdict for each given range.
//!
//! ```sh
//! cargo run -p echoloc-lab --example verdicts -- MAP X_M,Y_M,THETA_DEG R0,R1,… [RING]
//! cargo run -p echoloc-lab --example verdicts -- ../shared/data/maps/depot.yaml 5,5,0 1800,-,2400,900
//! ```
//!
//! MAP is a `.yaml` (ROS map_server), `.geojson` or compiled `.map`; ranges
//! are mm, `-` for no echo, one per transducer in ring order (fewer is
//! fine); RING is `pioneer16` (the default) or a ring JSON file.

use echoloc::credence::net::CredenceNet;
use echoloc::map::MapSource;
use echoloc::predict::{predict_ring, Pose};
use echoloc::referencing::{judge, Reading, VerdictConfig};
use echoloc_lab::predict::load_map;
use echoloc_lab::replay::parse_pose;
use echoloc_lab::simulate::filters::predict_params;
use echoloc_lab::LabError;

fn main() -> Result<(), LabError> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [map, pose, ranges, rest @ ..] = &args[..] else {
        return Err(LabError("usage: verdicts MAP X_M,Y_M,THETA_DEG R0,R1,… [RING]".into()));
    };
    let ring = echoloc_lab::ring::load(rest.first().map_or("pioneer16", String::as_str))?;
    let [x, y, th] = parse_pose(pose, "pose")?;
    let readings: Vec<Reading> = ranges
        .split(',')
        .map(|r| match r.trim() {
            "-" => Ok(Reading::NoEcho),
            t => t
                .parse::<u32>()
                .ok()
                .filter(|&mm| mm > 0)
                .map(|range_mm| Reading::Echo { range_mm })
                .ok_or_else(|| LabError(format!("range {t:?}: a positive number of mm, or - for no echo"))),
        })
        .collect::<Result<_, _>>()?;
    if readings.len() > ring.len() {
        return Err(LabError(format!("{} ranges for a ring of {}", readings.len(), ring.len())));
    }
    let loaded = load_map(map.as_ref(), 100)?;
    let map = loaded.view()?;
    let pose = Pose { x_mm: (x * 1000.0) as f32, y_mm: (y * 1000.0) as f32, heading_rad: th as f32 };
    let mut predicted = vec![None; ring.len()];
    predict_ring(
        &map,
        &pose,
        &ring,
        &predict_params(map.buffer_mm(), map.field()),
        &CredenceNet::shipped(),
        &mut predicted,
    )
    .map_err(|e| LabError(format!("prediction: {e}")))?;
    println!("transducer  predicted (mm)  kappa  reading (mm)  verdict");
    for (i, (p, r)) in predicted.iter().zip(&readings).enumerate() {
        let verdict = judge(*r, p.as_ref(), &VerdictConfig::POLAROID);
        let pred = p.map_or("-".into(), |p| p.range_mm.to_string());
        let kappa = p.map_or("-".into(), |p| format!("{:.2}", p.kappa.to_num::<f32>()));
        let read = match r {
            Reading::Echo { range_mm } => range_mm.to_string(),
            _ => "-".into(),
        };
        println!("{i:>10}  {pred:>14}  {kappa:>5}  {read:>12}  {verdict:?}");
    }
    Ok(())
}
