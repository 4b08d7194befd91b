//! Writes crates/roadtrack-cnn/tests/fixtures/centernet_parity.json (see
//! `roadtrack_learn::parity`).

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let f = roadtrack_learn::parity::make_fixture(11);
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../roadtrack-cnn/tests/fixtures/centernet_parity.json");
    std::fs::write(&path, serde_json::to_string(&f)? + "\n")?;
    println!("wrote {}", path.display());
    Ok(())
}
