use super::*;

#[test]
fn polyline_positions_and_mitred_offsets() {
    let p = Polyline::new(vec![[0.0, 0.0], [10.0, 0.0], [10.0, 10.0]]);
    assert_eq!(p.length_m(), 20.0);
    let (q, h) = p.at(15.0);
    assert!((q[0] - 10.0).abs() < 1e-12 && (q[1] - 5.0).abs() < 1e-12);
    assert!((h - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
    // Left offset of a left turn: the inner corner moves diagonally inwards.
    let o = p.offset(1.0);
    assert_eq!(o.points()[1], [9.0, 1.0]);
    assert_eq!(o.points()[0], [0.0, 1.0]);
}

#[test]
fn signal_cycles_through_green_yellow_red() {
    let plan = SignalPlan {
        phases: vec![
            Phase {
                groups: vec![0],
                green_s: 10.0,
                yellow_s: 2.0,
                all_red_s: 1.0,
            },
            Phase {
                groups: vec![1],
                green_s: 5.0,
                yellow_s: 2.0,
                all_red_s: 1.0,
            },
        ],
        offset_s: 0.0,
    };
    assert_eq!(plan.cycle_s(), 21.0);
    assert_eq!(plan.light(0, 5.0), Light::Green);
    assert_eq!(plan.light(0, 11.0), Light::Yellow);
    assert_eq!(plan.light(0, 12.5), Light::Red);
    assert_eq!(plan.light(1, 14.0), Light::Green);
    assert_eq!(plan.light(0, 21.0 + 5.0), Light::Green);
}

#[test]
fn intersection_routes_start_and_end_on_the_carriageway() {
    let cfg = SimConfig {
        scene: SceneKind::Intersection,
        ..SimConfig::default()
    };
    let s = Scene::build(&cfg, 0.0);
    assert_eq!(s.routes.len(), 12);
    for r in &s.routes {
        for p in r.path.points() {
            assert!(s.on_carriageway(*p), "{p:?}");
        }
        assert!((r.parts.last().map_or(0.0, |p| p.end_s) - r.path.length_m()).abs() < 1e-9);
    }
    // Pedestrian routes touch the carriageway only on crosswalks.
    for r in &s.pedestrian_routes {
        let n = (r.path.length_m() / 0.2) as usize;
        for i in 0..=n {
            let (p, _) = r.path.at(i as f64 * 0.2);
            assert!(!s.on_carriageway(p) || s.on_crosswalk(p), "{p:?}");
        }
    }
}
