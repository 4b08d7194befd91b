//! Fuzz tests of every file reader of roadtrack-core (issue 15, part 5): seeded structured
//! mutations of valid files plus raw bytes (see `fuzzkit`). Each reader must not panic and
//! must return either `Ok` with values in their documented ranges, or an error of the
//! documented kind naming the file: [`Error::Parse`] with the path and a line within the
//! file, or [`Error::Format`] with the path. Never an I/O error (the file exists) nor an
//! error without the path.
//!
//! `cargo test -p roadtrack-core --test fuzz_readers -- --ignored` runs the deep variant
//! (100 × the cases).

mod fuzzkit;

use fuzzkit::{DEEP, Syntax, file_error, run};
use roadtrack_core::Error;
use roadtrack_core::io::{
    detections, matches, mot, occlusion, points, seqinfo::SeqInfo, series, trajectories,
};
use std::path::Path;

/// A fuzz target: file name, seeds, syntax and the reader with its checks of an `Ok` result.
struct Target {
    name: &'static str,
    file: &'static str,
    seeds: &'static [&'static str],
    syntax: Syntax,
    read: fn(&Path) -> Result<Result<(), String>, Error>,
}

fn fuzz(t: &Target, cases: u32) {
    let dir = tempfile::tempdir().expect("temporary folder");
    let path = dir.path().join(t.file);
    run(t.name, cases, t.seeds, t.syntax, |bytes| {
        fuzzkit::write_case(&path, bytes)?;
        match (t.read)(&path) {
            Ok(checked) => checked,
            Err(e) => file_error(&e, &path, bytes),
        }
    });
}

fn ok_if(ok: bool, what: impl FnOnce() -> String) -> Result<(), String> {
    if ok { Ok(()) } else { Err(what()) }
}

fn finite(xs: &[f64]) -> bool {
    xs.iter().all(|x| x.is_finite())
}

const DETECTIONS: Target = Target {
    name: "detections_csv",
    file: "d.csv",
    seeds: &[
        "frame,id,x,y,w,h,r,g,b,class,score,area\n1,1,10.5,20,4,6,10,20,30,car,0.9,24\n1,2,30,40,5,5,0,0,255,person,1,25\n2,1,11,21,4,6,10,20,30,car,0.8,24\n",
        "x,y\n1,2\n3,4\n",
        "y,x,extra\n2,1,zz\n4,3,\n",
    ],
    syntax: Syntax::Csv,
    read: |p| {
        let d = detections::read_detections(p)?;
        Ok(d.iter().try_for_each(|d| {
            let size = d
                .size_px
                .is_none_or(|(w, h)| finite(&[w, h]) && w >= 0.0 && h >= 0.0);
            let rgb = d
                .colour_rgb
                .is_none_or(|c| c.iter().all(|v| (0.0..=255.0).contains(v)));
            let score = d.score.is_none_or(|s| (0.0..=1.0).contains(&s));
            let area = d.area_px.is_none_or(|a| a.is_finite() && a >= 0.0);
            ok_if(
                d.frame >= 1 && finite(&[d.pos_px.x, d.pos_px.y]) && size && rgb && score && area,
                || format!("out-of-range detection accepted: {d:?}"),
            )
        }))
    },
};

/// 3 000 cases.
#[test]
fn fuzz_detections_csv() {
    fuzz(&DETECTIONS, 3000);
}

const MATCHES: Target = Target {
    name: "matches_csv",
    file: "m.csv",
    seeds: &["id1,id2,probability\n1,4,0.75\n2,,1\n,9,\n3,5,0.5\n"],
    syntax: Syntax::Csv,
    read: |p| {
        let rows = matches::read_matches(p)?;
        Ok(rows.iter().try_for_each(|r| {
            ok_if(
                (r.id1.is_some() || r.id2.is_some())
                    && r.probability.is_none_or(|p| (0.0..=1.0).contains(&p)),
                || format!("bad match row accepted: {r:?}"),
            )
        }))
    },
};

/// 2 000 cases.
#[test]
fn fuzz_matches_csv() {
    fuzz(&MATCHES, 2000);
}

fn mot_box_ok(b: &roadtrack_core::BBox) -> bool {
    finite(&[b.left, b.top, b.width, b.height]) && b.width >= 0.0 && b.height >= 0.0
}

const MOT_TRACKS: Target = Target {
    name: "mot_tracks",
    file: "tracks.txt",
    seeds: &[
        "1,1,10,20,30,40,1,-1,-1,-1\n1,2,50,60,10,10,0.5,-1,-1,-1\n2,1,11,21,30,40,1,-1,-1,-1\n",
        "3, 7, 1.5, 2.5, 4, 5\n1,1,0,0,1,1\n",
    ],
    syntax: Syntax::Csv,
    read: |p| {
        let rows = mot::read_tracks(p)?;
        let sorted = rows
            .windows(2)
            .all(|w| (w[0].frame, w[0].id) < (w[1].frame, w[1].id));
        Ok(rows
            .iter()
            .try_for_each(|r| {
                ok_if(
                    r.frame >= 1 && mot_box_ok(&r.bbox) && r.conf.is_finite(),
                    || format!("bad track row accepted: {r:?}"),
                )
            })
            .and_then(|()| ok_if(sorted, || "rows not sorted and unique".into())))
    },
};

/// 3 000 cases.
#[test]
fn fuzz_mot_tracks() {
    fuzz(&MOT_TRACKS, 3000);
}

const MOT_GT: Target = Target {
    name: "mot_gt",
    file: "gt.txt",
    seeds: &[
        "1,1,10,20,30,40,1,1,1\n1,2,50,60,10,10,0,3,0.25\n2,1,11,21,30,40,1,1,0.5\n",
        "1,1,0,0,5,5\n2,1,1,1,5,5,1\n",
    ],
    syntax: Syntax::Csv,
    read: |p| {
        let rows = mot::read_gt(p)?;
        Ok(rows.iter().try_for_each(|r| {
            ok_if(
                r.frame >= 1
                    && mot_box_ok(&r.bbox)
                    && r.class >= 1
                    && (0.0..=1.0).contains(&r.visibility),
                || format!("bad gt row accepted: {r:?}"),
            )
        }))
    },
};

/// 3 000 cases.
#[test]
fn fuzz_mot_gt() {
    fuzz(&MOT_GT, 3000);
}

const MOT_DET: Target = Target {
    name: "mot_det",
    file: "det.txt",
    seeds: &[
        "1,-1,10,20,30,40,0.9,-1,-1,-1\n1,-1,50,60,10,10,0.5,-1,-1,-1\n3,-1,11,21,30,40,1,-1,-1,-1\n",
        "2,-1,0,0,5,5\n",
    ],
    syntax: Syntax::Csv,
    read: |p| {
        let d = mot::read_detections(p)?;
        Ok(d.iter().try_for_each(|d| {
            let size = d
                .size_px
                .is_some_and(|(w, h)| finite(&[w, h]) && w >= 0.0 && h >= 0.0);
            ok_if(
                d.frame >= 1 && d.id >= 1 && size && d.score.is_none_or(f64::is_finite),
                || format!("bad detection accepted: {d:?}"),
            )
        }))
    },
};

/// 2 000 cases.
#[test]
fn fuzz_mot_det() {
    fuzz(&MOT_DET, 2000);
}

const TRAJECTORIES: Target = Target {
    name: "trajectories_csv",
    file: "t.csv",
    seeds: &[
        "frame,time_s,id,class,x_px,y_px,w_px,h_px,score\n1,0,1,car,3,5,4,6,0.5\n2,0.1,1,car,4,5,4,6,0.5\n2,0.1,2,person,40,50,2,6,1\n",
        "frame,time_s,id,class,x_px,y_px,w_px,h_px,score,x_m,y_m,speed_mps,heading_deg\n1,0,1,car,3,5,4,6,0.5,1.5,-2,3.25,90\n2,0.1,1,car,4,5,4,6,0.5,1.6,-2,3.25,90\n",
    ],
    syntax: Syntax::Csv,
    read: |p| {
        let pts = trajectories::read_trajectories(p)?;
        Ok(pts.iter().try_for_each(|t| {
            let ground = t
                .ground
                .is_none_or(|g| finite(&[g.x_m, g.y_m, g.speed_mps, g.heading_deg]));
            ok_if(
                t.frame >= 1 && finite(&[t.time_s, t.score]) && mot_box_ok(&t.bbox) && ground,
                || format!("bad trajectory point accepted: {t:?}"),
            )
        }))
    },
};

/// 3 000 cases.
#[test]
fn fuzz_trajectories_csv() {
    fuzz(&TRAJECTORIES, 3000);
}

const MEASUREMENTS: Target = Target {
    name: "measurements_csv",
    file: "meas.csv",
    seeds: &["step,x,y\n0,1.5,-2\n3,0,9\n1,4,4\n"],
    syntax: Syntax::Csv,
    read: |p| {
        let m = points::read_measurements(p)?;
        let sorted = m.windows(2).all(|w| w[0].step <= w[1].step);
        Ok(ok_if(
            sorted && m.iter().all(|m| finite(&[m.pos.x, m.pos.y])),
            || format!("bad measurements accepted: {m:?}"),
        ))
    },
};

/// 2 000 cases.
#[test]
fn fuzz_measurements_csv() {
    fuzz(&MEASUREMENTS, 2000);
}

const ESTIMATES: Target = Target {
    name: "estimates_csv",
    file: "est.csv",
    seeds: &[
        "step,label,x,y,vx,vy,weight\n1,4,1,2,-0.5,0.25,0.9\n2,4,1.5,2,-0.5,0.25,0.8\n2,5,10,2,0,0,0.1\n",
    ],
    syntax: Syntax::Csv,
    read: |p| {
        let e = points::read_estimates(p)?;
        Ok(e.iter().try_for_each(|e| {
            ok_if(
                finite(&[e.pos.x, e.pos.y, e.vel.x, e.vel.y, e.weight]) && e.weight >= 0.0,
                || format!("bad estimate accepted: {e:?}"),
            )
        }))
    },
};

/// 2 000 cases.
#[test]
fn fuzz_estimates_csv() {
    fuzz(&ESTIMATES, 2000);
}

const SEQINFO: Target = Target {
    name: "seqinfo_ini",
    file: "seqinfo.ini",
    seeds: &[
        "[Sequence]\nname=s\nimDir=img1\nframeRate=10\nseqLength=3\nimWidth=64\nimHeight=48\nimExt=.png\n",
        "[Sequence]\nframeRate = 25\nseqLength = 600\nimWidth = 1920\nimHeight = 1080\n",
    ],
    syntax: Syntax::Ini,
    read: |p| {
        let s = SeqInfo::read(p)?;
        Ok(ok_if(
            s.frame_rate.is_finite()
                && s.frame_rate > 0.0
                && s.seq_length >= 1
                && s.im_width >= 1
                && s.im_height >= 1,
            || format!("bad seqinfo accepted: {s:?}"),
        ))
    },
};

/// 3 000 cases.
#[test]
fn fuzz_seqinfo_ini() {
    fuzz(&SEQINFO, 3000);
}

const OCCLUSION: Target = Target {
    name: "occlusion_csv",
    file: "occ.csv",
    seeds: &["frame,id,visible_blocks,separated\n3,7,2,1\n4,7,1,0\n4,8,0,1\n"],
    syntax: Syntax::Csv,
    read: |p| {
        occlusion::read_occlusion(p)?;
        Ok(Ok(()))
    },
};

/// 2 000 cases.
#[test]
fn fuzz_occlusion_csv() {
    fuzz(&OCCLUSION, 2000);
}

const SERIES: Target = Target {
    name: "series_csv",
    file: "sweep.csv",
    seeds: &["variant,dt,rate\nd,2,0.9\nc,1,0.8\nd,1,0.95\n"],
    syntax: Syntax::Csv,
    read: |p| {
        let s = series::read_series(p, "dt", "rate", Some("variant"))?;
        Ok(ok_if(
            !s.is_empty()
                && s.iter().all(|s| {
                    !s.points.is_empty()
                        && s.points.iter().all(|&(x, y)| finite(&[x, y]))
                        && s.points.windows(2).all(|w| w[0].0 <= w[1].0)
                }),
            || format!("bad series accepted: {s:?}"),
        ))
    },
};

/// 2 000 cases.
#[test]
fn fuzz_series_csv() {
    fuzz(&SERIES, 2000);
}

const ALL: [&Target; 11] = [
    &DETECTIONS,
    &MATCHES,
    &MOT_TRACKS,
    &MOT_GT,
    &MOT_DET,
    &TRAJECTORIES,
    &MEASUREMENTS,
    &ESTIMATES,
    &SEQINFO,
    &OCCLUSION,
    &SERIES,
];

/// The deep run: 100 × 2 000 cases for every reader above.
#[test]
#[ignore = "deep fuzzing, minutes; run with --ignored"]
fn fuzz_readers_deep() {
    for t in ALL {
        fuzz(t, 2000 * DEEP);
    }
}

/// The inputs the fuzz tests above found wrongly handled, with the outcome now expected.
#[test]
fn regressions() {
    let dir = tempfile::tempdir().expect("temporary folder");
    let parse_error = |file: &str, bytes: &[u8], read: fn(&Path) -> Result<(), Error>| {
        let p = dir.path().join(file);
        fuzzkit::write_case(&p, bytes).expect("write");
        match read(&p) {
            Err(Error::Parse {
                path, line, column, ..
            }) if path == p => (line, column),
            other => panic!("{file}: expected a parse error, got {other:?}"),
        }
    };
    // seqinfo.ini: a fraction passed the "positive" check and was cut to 0 frames.
    let seqinfo = |p: &Path| SeqInfo::read(p).map(|_| ());
    assert_eq!(
        parse_error(
            "seqinfo.ini",
            b"[Sequence]\nname=s\nimDir=img1\nframeRate=10\nseqLength= 0.23679990143441568\nimWidth=64\nimHeight=48\nimExt=.png\n",
            seqinfo,
        ),
        (5, "seqLength".into())
    );
    // Bytes that are not UTF-8 were an I/O error ("cannot access"), as if the file were
    // missing; now a parse error at their line.
    assert_eq!(
        parse_error("seqinfo.ini", b"[Sequence]\nframeRate=10\xff\n", seqinfo),
        (2, "-".into())
    );
    assert_eq!(
        parse_error("gt.txt", b"1,1,0,0,5,5\n2,1,\x80,0,5,5\n", |p| {
            mot::read_gt(p).map(|_| ())
        }),
        (2, "-".into())
    );
    assert_eq!(
        parse_error("tracks.txt", b"\xc3", |p| mot::read_tracks(p).map(|_| ())),
        (1, "-".into())
    );
    assert_eq!(
        parse_error("det.txt", b"1,-1,0,0,5,5\n\n\xfe", |p| {
            mot::read_detections(p).map(|_| ())
        }),
        (3, "-".into())
    );
}
