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
    let bad = format!("{HEAD}\n0,0,,0,0,0\n0.1,0,,0,0,1.6\n");
    let e = read(&bad, 1).unwrap_err();
    assert_eq!((e.line, matches!(e.problem, Problem::HeadingJump { .. })), (3, true));
}
