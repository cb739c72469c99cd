use super::*;

const HEAD: &str = "time_s,transducer,range_mm,odom_x_m,odom_y_m,odom_theta_rad";

#[test]
fn rows_read_with_and_without_reference_and_round_trip() {
    let text = format!(
        "# a comment\n{HEAD},ref_x_m,ref_y_m,ref_theta_rad\n0,0,1500.4,1,2,0.5,10,20,0.1\n0,1,,1,2,0.5,,,\n0.1,2, 2500 ,1.1,2,0.6,10.1,20,0.2\n"
    );
    let log = read(&text, 3).unwrap();
    assert_eq!(log.rows.len(), 3);
    assert_eq!(log.rows[0].range_mm, Some(1500));
    assert_eq!(log.rows[0].reference, Some([10.0, 20.0, 0.1]));
    assert_eq!((log.rows[1].range_mm, log.rows[1].reference), (None, None));
    assert_eq!(log.rows[2].range_mm, Some(2500));
    assert_eq!(log.rows[2].line, 5);
    let again = read(&write(&log.rows, true), 3).unwrap();
    let strip = |l: &Log| l.rows.iter().map(|r| Row { line: 0, ..*r }).collect::<Vec<_>>();
    assert_eq!(strip(&again), strip(&log));
    // Columns in another order read the same.
    let shuffled = "odom_theta_rad,range_mm,transducer,time_s,odom_y_m,odom_x_m\n0.5,1500,0,0,2,1\n";
    let r = read(shuffled, 3).unwrap().rows[0];
    assert_eq!((r.odometry, r.range_mm, r.transducer), ([1.0, 2.0, 0.5], Some(1500), 0));
}

#[test]
fn f64_values_survive_the_text() {
    let v = [0.1 + 0.2, -1.8414213562373098, 1e-9, 123456.789012345, std::f64::consts::PI];
    let rows: Vec<Row> = v
        .iter()
        .enumerate()
        .map(|(i, &x)| Row {
            time_s: i as f64 * 0.1,
            transducer: 0,
            range_mm: Some(1000),
            odometry: [x, -x, 0.0],
            reference: None,
            line: i as u64 + 2,
        })
        .collect();
    assert_eq!(read(&write(&rows, false), 1).unwrap().rows, rows);
}

#[test]
fn heading_wraps_are_odometry_but_jumps_are_not() {
    // −π+0.01 after π−0.01 is a turn of 0.02 rad through the wrap.
    let ok = format!("{HEAD}\n0,0,,0,0,3.13\n0.1,0,,0,0,-3.13\n");
    assert!(read(&ok, 1).is_ok());
    // 1.6 rad in 0.1 s is 16 rad/s.
    let bad = format!("{HEAD}\n0,0,,0,0,0\n0.1,0,,0,0,1.6\n");
    let e = read(&bad, 1).unwrap_err();
    assert_eq!((e.line, matches!(e.problem, Problem::HeadingJump { .. })), (3, true));
}

/// A whole-ring reading every 0.5–1 m, turning up to 80° between them (a
/// real logger's rate, issue #35): every turn at the rate real robots turn.
fn sparse_log(theta_of: impl Fn(f64) -> f64) -> String {
    let mut s = format!("{HEAD}\n");
    let mut heading = 0.0f64;
    let mut t = 0.0;
    for k in 0..40 {
        // Turns of 80°, −60°, 35°, 0°, … every 2.5 s (32°/s at most).
        let turn = [80.0, -60.0, 35.0, 0.0][k % 4];
        heading += f64::to_radians(turn);
        t += 2.5;
        for tr in 0..4 {
            s.push_str(&format!("{t},{tr},,{},{},{}\n", k as f64 * 0.8, 0.0, theta_of(heading)));
        }
    }
    s
}

#[test]
fn sparse_real_logs_pass_wrapped_or_cumulative() {
    let wrapped = |h: f64| (h + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU) - std::f64::consts::PI;
    assert!(read(&sparse_log(wrapped), 4).is_ok());
    assert!(read(&sparse_log(|h| h), 4).is_ok());
    // Cumulative past several turns: the steps are read as logged.
    assert!(read(&sparse_log(|h| h + 20.0), 4).is_ok());
}

#[test]
fn degrees_logged_as_radians_are_refused_at_any_rate() {
    // The same sparse log in degrees, wrapped at ±180 and cumulative.
    let wrapped_deg = |h: f64| ((h.to_degrees() + 180.0).rem_euclid(360.0)) - 180.0;
    for text in [sparse_log(wrapped_deg), sparse_log(f64::to_degrees)] {
        let e = read(&text, 4).unwrap_err();
        assert!(matches!(e.problem, Problem::HeadingJump { .. }), "{e}");
        assert!(e.to_string().contains("degrees logged as radians"), "{e}");
    }
    // At 10 Hz a robot turning 20°/s: 2° a row, 20 "rad"/s.
    let mut s = format!("{HEAD}\n");
    for k in 0..50 {
        s.push_str(&format!("{},0,,0,0,{}\n", k as f64 * 0.1, k as f64 * 2.0));
    }
    let e = read(&s, 1).unwrap_err();
    assert!(matches!(e.problem, Problem::HeadingJump { .. }), "{e}");
}
