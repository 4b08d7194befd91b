//! Tests of the simulator config (defaults, validation).

use super::*;

#[test]
fn defaults_are_seed_000_and_the_issue() {
    let c = SimConfig::default();
    assert_eq!((c.width, c.height, c.fps, c.frames), (640, 480, 10.0, 300));
    assert_eq!(c.road.length_m, 700.0);
    assert_eq!(c.road.lanes, 2);
    assert_eq!(c.aerial.metres_per_pixel, 0.33);
    assert_eq!(c.oblique.height_m, 8.0);
    assert!(c.validate().is_ok());
    let white_silver_black_grey: f64 = c.vehicles.colours[..4].iter().map(|k| k.share).sum();
    assert!(white_silver_black_grey > 0.7);
}

#[test]
fn partial_toml_keeps_defaults_and_typos_are_rejected() -> Result<()> {
    let p = std::path::Path::new("sim.toml");
    let c = SimConfig::from_toml_str("scene = \"crossing\"\n[road]\nlanes = 3\n", p)?;
    assert_eq!(c.scene, SceneKind::Crossing);
    assert_eq!(c.road.lanes, 3);
    assert_eq!(c.road.length_m, 700.0);
    assert!(SimConfig::from_toml_str("[road]\nlane = 3\n", p).is_err());
    assert!(SimConfig::from_toml_str("fps = -1.0\n", p).is_err());
    let back = SimConfig::from_toml_str(&SimConfig::default().to_toml(), p)?;
    assert_eq!(back, SimConfig::default());
    Ok(())
}
