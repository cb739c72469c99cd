/// Paths that are not bags are named, with what is wrong.
#[test]
fn paths_that_are_not_bags() {
    let map = shared_map("depot.yaml");
    let dir = tmp("bag", "not-a-bag-dir");
    std::fs::create_dir_all(&dir).unwrap();
    let text = tmp("bag", "notes.mcap");
    std::fs::write(&text, "these are notes, not a recording").unwrap();
    for (bag, message) in [
        (tmp("bag", "missing"), "missing: no such file or directory".to_string()),
        (dir.clone(), format!("{}: No such file or directory", dir.join("metadata.yaml").display())),
        (text.clone(), "notes.mcap: unreadable MCAP: not an MCAP file (no magic bytes)".to_string()),
    ] {
        let o = lab().args(["replay", "--map", s(&map), "--bag", s(&bag)]).output().unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success() && err.contains(&message), "expected {message:?}, got {err}");
    }
    // --log and --bag together, or neither, are refused by the command line.
    let o = lab().args(["replay", "--map", s(&map), "--bag", s(&text), "--log", s(&text)]).output().unwrap();
    assert!(String::from_utf8_lossy(&o.stderr).contains("cannot be used with"));
    let o = lab().args(["replay", "--map", s(&map)]).output().unwrap();
    assert!(String::from_utf8_lossy(&o.stderr).contains("--log <LOG>"));
}
