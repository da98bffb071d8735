//! The learning-curve plotter on synthetic run directories: it renders a non-blank PNG of the
//! requested size, draws a group of seeds as a line over a band, draws a panel per hazard kind
//! of the episodes (none without), and reads the metrics files strictly except for a truncated
//! last line.

use std::collections::HashMap;
use std::fmt::Write as _;
use std::fs;
use std::io::BufReader;
use std::path::{Path, PathBuf};

use learner::telemetry::records::{EpisodeRecord, RecordsError, TrainRecord, read_episodes, read_train};
use learner_cli::plot::{PlotError, PlotOptions, RunGroup, XAxis, plot_groups, plot_runs};

/// A small deterministic noise source in [-1, 1).
struct Noise(u64);

impl Noise {
    fn next(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 11) as f64 / (1u64 << 52) as f64 - 1.0
    }
}

fn episode(i: u64, ret: f64) -> EpisodeRecord {
    EpisodeRecord {
        time_secs: i as f64 * 0.5,
        episode_index: i,
        actor_id: format!("actor-{}", i % 2),
        env: (i % 4) as u32,
        episode_return: ret,
        steps: 100,
        arrived: ret > 5.0,
        collision: if ret > 5.0 { None } else { Some("vehicle".into()) },
        scenario: "right_turn".into(),
        hazard: None,
        outcome: if ret > 5.0 { "arrived" } else { "collision" }.into(),
        learner_step: i * 10,
        env_steps: i * 100,
    }
}

fn train(step: u64, loss: Option<f64>, mean_q: Option<f64>) -> TrainRecord {
    TrainRecord {
        time_secs: step as f64 / 100.0,
        learner_step: step,
        env_steps: step * 4,
        transitions_stored: step * 4,
        loss,
        mean_q,
        updates_per_sec: 100.0,
        env_steps_per_sec: 400.0,
        epsilon: 0.1,
        replay_size: step * 4,
        weights_version: step / 100,
        episodes: step / 10,
        ..TrainRecord::default()
    }
}

fn write_jsonl<T: serde::Serialize>(path: &Path, records: &[T]) {
    let mut text = String::new();
    for r in records {
        writeln!(text, "{}", serde_json::to_string(r).unwrap()).unwrap();
    }
    fs::write(path, text).unwrap();
}

/// A run whose return rises from about -10 to `final_return` with noise, and whose loss falls.
fn synthetic_run(dir: &Path, episodes: u64, final_return: f64, seed: u64) {
    fs::create_dir_all(dir).unwrap();
    let mut noise = Noise(seed);
    let eps: Vec<_> = (1..=episodes)
        .map(|i| {
            let progress = i as f64 / episodes as f64;
            episode(i, -10.0 + (final_return + 10.0) * progress + 6.0 * noise.next())
        })
        .collect();
    write_jsonl(&dir.join("episodes.jsonl"), &eps);
    let steps = episodes * 10;
    let train_records: Vec<_> = (0..=steps / 100)
        .map(|k| {
            let step = k * 100;
            if k < 3 {
                // Before training starts.
                train(step, None, None)
            } else {
                let t = step as f64 / steps as f64;
                let loss = 2.0 * (-4.0 * t).exp() * (1.0 + 0.2 * noise.next());
                let q = -5.0 + (final_return + 5.0) * t + 0.5 * noise.next();
                train(step, Some(loss), Some(q))
            }
        })
        .collect();
    write_jsonl(&dir.join("train.jsonl"), &train_records);
}

/// Decodes an RGB(A) 8-bit PNG: (width, height, pixels as RGB).
fn decode_png(path: &Path) -> (u32, u32, Vec<[u8; 3]>) {
    let decoder = png::Decoder::new(BufReader::new(fs::File::open(path).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    assert_eq!(info.bit_depth, png::BitDepth::Eight);
    let channels = match info.color_type {
        png::ColorType::Rgb => 3,
        png::ColorType::Rgba => 4,
        other => panic!("unexpected colour type {other:?}"),
    };
    let pixels = buf[..info.buffer_size()].chunks_exact(channels).map(|c| [c[0], c[1], c[2]]).collect();
    (info.width, info.height, pixels)
}

/// Colours that are clearly not a shade of gray, with more than `min_pixels` pixels each.
fn line_colours(pixels: &[[u8; 3]], min_pixels: usize) -> Vec<[u8; 3]> {
    let mut counts: HashMap<[u8; 3], usize> = HashMap::new();
    for p in pixels {
        let (lo, hi) = (p.iter().min().unwrap(), p.iter().max().unwrap());
        if hi - lo > 40 {
            *counts.entry(*p).or_default() += 1;
        }
    }
    counts.into_iter().filter(|&(_, n)| n > min_pixels).map(|(c, _)| c).collect()
}

#[test]
fn two_runs_render_to_a_png_with_a_line_per_run() {
    let tmp = tempfile::tempdir().unwrap();
    let a = tmp.path().join("hybrid");
    let b = tmp.path().join("drl");
    synthetic_run(&a, 400, 10.0, 1);
    synthetic_run(&b, 300, 2.0, 2);
    let out = tmp.path().join("curves.png");
    let opts = PlotOptions::default();
    let summary = plot_runs(&[a, b], &out, &opts).unwrap();

    assert_eq!(summary.runs.len(), 2);
    let (ra, rb) = (&summary.runs[0], &summary.runs[1]);
    assert_eq!((ra.name.as_str(), ra.episodes, ra.train_points), ("hybrid", 400, 41));
    assert_eq!((rb.name.as_str(), rb.episodes, rb.train_points), ("drl", 300, 31));
    // The last window of 50 episodes averages a return rising to the final one, minus noise.
    let fa = ra.final_smoothed_return.unwrap();
    let fb = rb.final_smoothed_return.unwrap();
    assert!((6.0..11.0).contains(&fa), "{fa}");
    assert!((-1.5..2.5).contains(&fb), "{fb}");

    let (w, h, pixels) = decode_png(&out);
    assert_eq!((w, h), (opts.width, opts.height));
    assert_eq!(pixels.len(), (w * h) as usize);
    let colours = line_colours(&pixels, 1000);
    assert!(colours.len() >= 2, "expected two line colours with many pixels each, found {colours:?}");
    // Text and axes: plenty of dark pixels, but far from all.
    let dark = pixels.iter().filter(|p| p.iter().all(|&c| c < 100)).count();
    assert!(dark > 2000 && dark < pixels.len() / 4, "{dark} dark pixels");

    if let Some(keep) = std::env::var_os("PLOT_EXAMPLE_OUT") {
        fs::copy(&out, keep).unwrap();
    }
}

#[test]
fn a_truncated_last_line_is_skipped_and_unknown_fields_ignored() {
    let tmp = tempfile::tempdir().unwrap();
    let path = tmp.path().join("episodes.jsonl");
    let mut text = String::new();
    for i in 1..=3 {
        let mut v = serde_json::to_value(episode(i, i as f64)).unwrap();
        v["some_future_field"] = serde_json::json!({"nested": [1, 2]});
        writeln!(text, "{v}").unwrap();
    }
    text.push_str(r#"{"time_secs": 2.0, "episode_index": 4, "act"#);
    fs::write(&path, text).unwrap();
    let eps = read_episodes(&path).unwrap();
    assert_eq!(eps.iter().map(|e| e.episode_index).collect::<Vec<_>>(), [1, 2, 3]);
    assert_eq!(eps[2].episode_return, 3.0);

    let train_path = tmp.path().join("train.jsonl");
    let full = serde_json::to_string(&train(100, Some(0.5), None)).unwrap();
    fs::write(&train_path, format!("{full}\n\n{}", &full[..full.len() / 2])).unwrap();
    let records = read_train(&train_path).unwrap();
    assert_eq!(records.len(), 1);
    assert_eq!((records[0].loss, records[0].mean_q), (Some(0.5), None));
}

#[test]
fn a_malformed_middle_line_is_an_error_naming_file_and_line() {
    let tmp = tempfile::tempdir().unwrap();
    let run = tmp.path().join("run1");
    fs::create_dir(&run).unwrap();
    let path = run.join("episodes.jsonl");
    let good = serde_json::to_string(&episode(1, 0.0)).unwrap();
    fs::write(&path, format!("{good}\n{{\"episode_index\": \"two\"}}\n{good}\n")).unwrap();

    let err = read_episodes(&path).unwrap_err();
    assert!(matches!(&err, RecordsError::Parse { line: 2, path: p, .. } if *p == path), "{err:?}");
    let msg = err.to_string();
    assert!(msg.contains(&path.display().to_string()) && msg.contains("line 2"), "{msg}");

    // The same through plot_runs.
    let err = plot_runs(&[run], &tmp.path().join("out.png"), &PlotOptions::default()).unwrap_err();
    assert!(matches!(err, PlotError::Records(RecordsError::Parse { line: 2, .. })), "{err:?}");
}

#[test]
fn a_run_without_episodes_is_an_error_naming_it() {
    let tmp = tempfile::tempdir().unwrap();
    let good = tmp.path().join("good");
    synthetic_run(&good, 20, 1.0, 3);
    let missing = tmp.path().join("no-metrics-here");
    fs::create_dir(&missing).unwrap();
    let out = tmp.path().join("out.png");
    let err = plot_runs(&[good, missing.clone()], &out, &PlotOptions::default()).unwrap_err();
    assert!(matches!(&err, PlotError::MissingEpisodes { dir } if *dir == missing), "{err:?}");
    assert!(err.to_string().contains("no-metrics-here"), "{err}");
    assert!(!out.exists());
}

#[test]
fn empty_runs_are_plotted_as_empty() {
    let tmp = tempfile::tempdir().unwrap();
    let empty = tmp.path().join("empty");
    fs::create_dir(&empty).unwrap();
    fs::write(empty.join("episodes.jsonl"), "").unwrap();
    let short = tmp.path().join("short");
    synthetic_run(&short, 7, 1.0, 4);
    let out = tmp.path().join("out.png");
    let opts = PlotOptions { smoothing: 10, width: 640, height: 480, ..PlotOptions::default() };
    let summary = plot_runs(&[empty.clone(), short], &out, &opts).unwrap();
    assert_eq!(summary.runs[0].name, "empty");
    assert_eq!((summary.runs[0].episodes, summary.runs[0].train_points, summary.runs[0].final_smoothed_return), (0, 0, None));
    // Seven episodes are fewer than the window: the window shrinks so that a curve is drawn.
    assert_eq!(summary.runs[1].episodes, 7);
    assert!(summary.runs[1].final_smoothed_return.is_some());
    assert_eq!(decode_png(&out).0, 640);

    // Only the empty run: every panel is empty, and that is still a plot.
    let summary = plot_runs(&[empty], &out, &opts).unwrap();
    assert_eq!(summary.runs[0].episodes, 0);
    let (w, h, _) = decode_png(&out);
    assert_eq!((w, h), (640, 480));
}

#[test]
fn bad_options_and_outputs_are_errors() {
    let tmp = tempfile::tempdir().unwrap();
    let run = tmp.path().join("run");
    synthetic_run(&run, 20, 1.0, 5);
    let runs = [run];
    let out = tmp.path().join("out.png");
    assert!(matches!(plot_runs(&[] as &[PathBuf], &out, &PlotOptions::default()), Err(PlotError::NoRuns)));
    let zero = PlotOptions { smoothing: 0, ..PlotOptions::default() };
    assert!(matches!(plot_runs(&runs, &out, &zero), Err(PlotError::Options(_))));
    assert!(matches!(plot_runs(&runs, &tmp.path().join("out.svg"), &PlotOptions::default()), Err(PlotError::Options(_))));
    let err = plot_runs(&runs, &tmp.path().join("no-such-dir/out.png"), &PlotOptions::default()).unwrap_err();
    assert!(matches!(&err, PlotError::Draw { .. }) && err.to_string().contains("no-such-dir"), "{err:?}");
}

#[test]
fn periodic_evaluations_get_a_panel_and_give_the_time_to_competence() {
    use learner::telemetry::records::{EvalRecord, EvalRouteRecord};
    let tmp = tempfile::tempdir().unwrap();
    let run = tmp.path().join("hybrid");
    synthetic_run(&run, 300, 40.0, 5);
    let eval = |minutes: f64, mastered: u32| EvalRecord {
        time_secs: minutes * 60.0,
        env_steps: (minutes * 1000.0) as u64,
        learner_step: (minutes * 10.0) as u64,
        weights_version: 1,
        town: "default_town".into(),
        runs: 2,
        route_types_mastered: mastered,
        mean_return: f64::from(mastered) * 10.0,
        completion_rate: f64::from(mastered) / 7.0,
        routes: vec![EvalRouteRecord { route: "straight_urban".into(), completed: 2, mean_return: 50.0 }],
        driving_score: None,
        hazard_driving_score: None,
        hazard_kinds: Vec::new(),
        selection_score: None,
        best: false,
    };
    write_jsonl(&run.join("eval.jsonl"), &[eval(2.0, 1), eval(4.0, 4), eval(6.0, 5), eval(8.0, 7)]);
    let out = tmp.path().join("curves.png");
    let summary = plot_runs(std::slice::from_ref(&run), &out, &PlotOptions::default()).unwrap();
    assert_eq!(summary.runs[0].eval_points, 4);
    assert_eq!(summary.runs[0].minutes_to_competence, Some(6.0));
    // The same run without evaluations: three panels, no time to competence.
    fs::remove_file(run.join("eval.jsonl")).unwrap();
    let without = plot_runs(&[run], &tmp.path().join("plain.png"), &PlotOptions::default()).unwrap();
    assert_eq!((without.runs[0].eval_points, without.runs[0].minutes_to_competence), (0, None));
    // The panel is drawn: the run's colour appears in the bottom quarter only with evaluations.
    let bottom_colour_pixels = |path: &Path| {
        let (w, h, px) = decode_png(path);
        px[(w * h * 3 / 4) as usize..].iter().filter(|p| p.iter().max().unwrap() - p.iter().min().unwrap() > 40).count()
    };
    assert!(bottom_colour_pixels(&out) > bottom_colour_pixels(&tmp.path().join("plain.png")) + 100);
}

#[test]
fn a_group_of_seeds_draws_its_mean_over_a_band_beside_a_single_run() {
    let tmp = tempfile::tempdir().unwrap();
    let seeds: Vec<PathBuf> = (0..3).map(|s| tmp.path().join(format!("hybrid-seed{s}"))).collect();
    for (s, dir) in seeds.iter().enumerate() {
        synthetic_run(dir, 300, 8.0 + 2.0 * s as f64, 10 + s as u64);
    }
    let single = tmp.path().join("drl");
    synthetic_run(&single, 300, 0.0, 20);
    let group_arg = format!("hybrid={}", seeds.iter().map(|d| d.display().to_string()).collect::<Vec<_>>().join(","));
    let groups = [RunGroup::parse(&group_arg).unwrap(), RunGroup::parse(single.to_str().unwrap()).unwrap()];
    assert_eq!((groups[0].label(), groups[0].dirs()), (Some("hybrid"), seeds.as_slice()));

    for x in [XAxis::Minutes, XAxis::EnvSteps] {
        let out = tmp.path().join(format!("seeds-{x:?}.png"));
        let opts = PlotOptions { x, ..PlotOptions::default() };
        let summary = plot_groups(&groups, &out, &opts).unwrap();
        let run_groups: Vec<&str> = summary.runs.iter().map(|r| r.group.as_str()).collect();
        assert_eq!(run_groups, ["hybrid", "hybrid", "hybrid", "drl"]);
        let lines: Vec<(&str, usize)> = summary.groups.iter().map(|g| (g.label.as_str(), g.runs)).collect();
        assert_eq!(lines, [("hybrid", 3), ("drl", 1)]);
        let finals: Vec<f64> = summary.runs[..3].iter().map(|r| r.final_smoothed_return.unwrap()).collect();
        let mean = summary.groups[0].mean_final_smoothed_return.unwrap();
        assert!((mean - finals.iter().sum::<f64>() / 3.0).abs() < 1e-9, "{mean} {finals:?}");

        assert!(fs::read(&out).unwrap().starts_with(b"\x89PNG\r\n\x1a\n"), "{} is not a PNG", out.display());
        let (w, h, pixels) = decode_png(&out);
        assert_eq!((w, h), (opts.width, opts.height));
        // Both lines, in their own colours (blue and orange, the first two).
        let colours = line_colours(&pixels, 1000);
        assert!(colours.contains(&[31, 119, 180]) && colours.contains(&[255, 127, 14]), "{x:?}: {colours:?}");
        // The group's band: its blue at 20% over white (or over a light grid line).
        let band =
            pixels.iter().filter(|p| (200..=222).contains(&p[0]) && (220..=234).contains(&p[1]) && (234..=244).contains(&p[2])).count();
        assert!(band > 2000, "{x:?}: {band} band pixels");
    }

    // A group of one run draws no band: no band-coloured pixels.
    let one = [RunGroup::labelled("hybrid", vec![seeds[0].clone()]).unwrap()];
    let out = tmp.path().join("one.png");
    let summary = plot_groups(&one, &out, &PlotOptions::default()).unwrap();
    assert_eq!((summary.groups[0].label.as_str(), summary.groups[0].runs), ("hybrid", 1));
    let (_, _, pixels) = decode_png(&out);
    let band = pixels.iter().filter(|p| (200..=222).contains(&p[0]) && (220..=234).contains(&p[1]) && (234..=244).contains(&p[2])).count();
    assert!(band < 200, "{band} band pixels without a band");
}

#[test]
fn hazard_episodes_get_a_panel_per_kind_and_runs_without_them_none() {
    let tmp = tempfile::tempdir().unwrap();
    let run = tmp.path().join("hazards");
    synthetic_run(&run, 400, 10.0, 6);
    // Every other episode has a hazard: stalled cars are passed more and more often, cut-ins
    // always end in a collision.
    let mut eps = read_episodes(&run.join("episodes.jsonl")).unwrap();
    for e in &mut eps {
        let i = e.episode_index;
        let (hazard, arrived) = match i % 4 {
            0 => (Some("stalled_car"), i % 8 == 0 || i > 200),
            2 => (Some("cut_in"), false),
            _ => (None, e.arrived),
        };
        e.hazard = hazard.map(str::to_owned);
        e.arrived = arrived;
        e.collision = (!arrived).then(|| "vehicle".to_owned());
        e.outcome = if arrived { "arrived" } else { "collision" }.into();
    }
    write_jsonl(&run.join("episodes.jsonl"), &eps);
    let opts = PlotOptions { x: XAxis::EnvSteps, ..PlotOptions::default() };
    let out = tmp.path().join("hazards.png");
    let summary = plot_runs(std::slice::from_ref(&run), &out, &opts).unwrap();
    assert_eq!(summary.hazard_kinds, ["stalled_car", "cut_in"]);
    // Five panels: the last (cut-ins) holds the run's blue, flat at a collision share of 1.
    let (w, h, pixels) = decode_png(&out);
    let blue_rows: Vec<usize> = (0..h as usize)
        .filter(|&y| pixels[y * w as usize..(y + 1) * w as usize].iter().filter(|&&p| p == [31, 119, 180]).count() > w as usize / 3)
        .collect();
    assert!(blue_rows.iter().any(|&y| y > h as usize * 4 / 5), "no long blue line in the bottom panel: {blue_rows:?}");

    // The same run written before hazards and outcomes were recorded: lines without either field
    // parse, and there is no hazard panel.
    // The same directory name as the run's: the legends match.
    let old = tmp.path().join("old").join("hazards");
    fs::create_dir_all(&old).unwrap();
    let mut text = String::new();
    for e in &eps {
        let mut v = serde_json::to_value(e).unwrap();
        let fields = v.as_object_mut().unwrap();
        fields.remove("hazard");
        fields.remove("outcome");
        writeln!(text, "{v}").unwrap();
    }
    fs::write(old.join("episodes.jsonl"), text).unwrap();
    fs::copy(run.join("train.jsonl"), old.join("train.jsonl")).unwrap();
    let old_out = tmp.path().join("old.png");
    let summary = plot_runs(std::slice::from_ref(&old), &old_out, &opts).unwrap();
    assert_eq!((summary.runs[0].episodes, summary.hazard_kinds.len()), (400, 0));
    // Without hazards the plot is the three panels it always was: the same picture as a run whose
    // lines carry the fields with no hazard.
    for e in &mut eps {
        e.hazard = None;
    }
    write_jsonl(&run.join("episodes.jsonl"), &eps);
    let plain_out = tmp.path().join("plain.png");
    plot_runs(&[run], &plain_out, &opts).unwrap();
    assert_eq!(decode_png(&old_out).2, decode_png(&plain_out).2);
}
