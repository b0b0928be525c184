//! `usar-bench` as a user runs it: the defects were a 30 s wait and "nothing from the
//! server" for 1000 UAVs on the default map, and NaN figures for `--uavs 0`.

use std::process::Command;

fn bench(args: &[&str]) -> (Option<i32>, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_usar-bench"))
        .args(args)
        .env("RUST_BACKTRACE", "0")
        .output()
        .unwrap();
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn a_thousand_uavs_get_a_layout_that_fits_the_default_map() {
    let (code, out, err) = bench(&["--uavs", "1000", "--sim-only", "--seconds", "0.05"]);
    assert_eq!(code, Some(0), "{err}");
    assert!(out.contains("1000 robots (1000 in the world)"), "{out}");
}

#[test]
fn a_layout_that_cannot_fit_is_refused_at_once_with_what_to_pass() {
    let (code, _, err) = bench(&["--uavs", "1000", "--layers", "1", "--sim-only"]);
    assert_eq!(code, Some(1));
    assert!(
        err.contains("do not fit on map EmptyRoom") && err.contains("--map city"),
        "{err}"
    );
}

#[test]
fn zero_uavs_is_a_usage_error_not_nan() {
    let (code, out, err) = bench(&["--uavs", "0"]);
    assert_eq!(code, Some(2), "{err}");
    assert!(
        !out.contains("NaN") && err.contains("at least 1"),
        "{out}{err}"
    );
}
