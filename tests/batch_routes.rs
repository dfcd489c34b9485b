//! `mpgdrive routes` as a library: Poisson demand from the I-80 base file, shares and seeds.

use mpgdrive::batch::routes::{DemandSpec, Streams, combined_route_files, flows_by_stream, generate};
use mpgdrive::sumo::MergeGeometry;
use std::path::{Path, PathBuf};

fn out_dir(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("routes-{name}"));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

fn i80() -> (PathBuf, MergeGeometry) {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("sumo_nets/i80_merge");
    (
        dir.join("i80.rou.xml"),
        MergeGeometry::load(&dir.join("merge.toml")).unwrap(),
    )
}

/// (depart, type, route) of every vehicle of a generated file.
fn vehicles(path: &Path) -> Vec<(f64, String, String)> {
    let text = std::fs::read_to_string(path).unwrap();
    let doc = roxmltree::Document::parse(&text).unwrap();
    doc.descendants()
        .filter(|n| n.has_tag_name("vehicle"))
        .map(|n| {
            (
                n.attribute("depart").unwrap().parse().unwrap(),
                n.attribute("type").unwrap().to_owned(),
                n.attribute("route").unwrap().to_owned(),
            )
        })
        .collect()
}

#[test]
fn demand_scales_shares_and_seeds() {
    let (base, geometry) = i80();
    let out = out_dir("i80");
    let spec = DemandSpec {
        scales: vec![1.0, 2.0],
        ramp_share: Some(0.2),
        controllable_shares: vec![0.5],
        mainline_share: None,
        seeds: vec![0, 1],
        begin: 0.0,
        duration: 3600.0,
        streams: Default::default(),
        loaded: Vec::new(),
    };
    let manifest = generate(&base, std::slice::from_ref(&geometry), &spec, &out).unwrap();
    assert_eq!(manifest.len(), 4);
    for entry in &manifest {
        let v = vehicles(&out.join(&entry.file));
        assert_eq!(v.len(), entry.vehicles);
        // Poisson counts: the base flows run 900 s, so the mean is 8,200 veh/h x scale / 4
        // (the duration, 3,600 s, does not extend them); 4 standard deviations.
        let mean = 8200.0 * entry.scale / 4.0;
        assert!(
            (v.len() as f64 - mean).abs() < 4.0 * mean.sqrt(),
            "{} vehicles, mean {mean}",
            v.len()
        );
        assert!(v.windows(2).all(|w| w[0].0 <= w[1].0), "departures sorted");
        let ramp: Vec<_> = v.iter().filter(|x| x.2 == "onramp").collect();
        // Binomial shares: 20% from the ramp, half of those controllable.
        let share = ramp.len() as f64 / v.len() as f64;
        assert!(
            (share - 0.2).abs() < 4.0 * (0.2 * 0.8 / v.len() as f64).sqrt(),
            "ramp share {share}"
        );
        let ctrl = ramp.iter().filter(|x| x.1 == "ctrl").count() as f64 / ramp.len() as f64;
        assert!(
            (ctrl - 0.5).abs() < 4.0 * (0.25 / ramp.len() as f64).sqrt(),
            "controllable {ctrl}"
        );
        assert!(ramp.iter().all(|x| x.1 == "ctrl" || x.1 == "human_ramp"));
        assert!(v.iter().filter(|x| x.2 == "freeway").all(|x| x.1 == "human"));
    }
    // The same seed gives the same file; another seed another one.
    let again = out_dir("i80-again");
    generate(&base, std::slice::from_ref(&geometry), &spec, &again).unwrap();
    let read = |d: &Path, f: &str| std::fs::read_to_string(d.join(f)).unwrap();
    assert_eq!(read(&out, &manifest[0].file), read(&again, &manifest[0].file));
    assert_ne!(read(&out, &manifest[0].file), read(&out, &manifest[1].file));
}

#[test]
fn out_of_range_shares_are_refused() {
    let (base, geometry) = i80();
    let spec = DemandSpec {
        scales: vec![1.0],
        ramp_share: Some(1.5),
        controllable_shares: Vec::new(),
        mainline_share: None,
        seeds: vec![0],
        begin: 0.0,
        duration: 60.0,
        streams: Default::default(),
        loaded: Vec::new(),
    };
    let err = generate(&base, std::slice::from_ref(&geometry), &spec, &out_dir("bad")).unwrap_err();
    assert!(err.to_string().contains("--ramp-share 1.5"), "{err}");
}

#[test]
fn a_controllable_share_sweep_keeps_the_arrivals_and_changes_the_types() {
    let (base, geometry) = i80();
    let out = out_dir("sweep");
    let spec = DemandSpec {
        scales: vec![1.0],
        ramp_share: None,
        controllable_shares: vec![0.0, 1.0],
        mainline_share: None,
        seeds: vec![3],
        begin: 0.0,
        duration: 300.0,
        streams: Default::default(),
        loaded: Vec::new(),
    };
    let manifest = generate(&base, std::slice::from_ref(&geometry), &spec, &out).unwrap();
    let files: Vec<(&str, Option<f64>)> = manifest
        .iter()
        .map(|e| (e.file.as_str(), e.controllable_share))
        .collect();
    assert_eq!(
        files,
        [
            ("i80_d1.00_c0.00_s3.rou.xml", Some(0.0)),
            ("i80_d1.00_c1.00_s3.rou.xml", Some(1.0))
        ]
    );
    let (none, all) = (vehicles(&out.join(files[0].0)), vehicles(&out.join(files[1].0)));
    let when = |v: &[(f64, String, String)]| v.iter().map(|x| (x.0, x.2.clone())).collect::<Vec<_>>();
    assert_eq!(when(&none), when(&all), "same departures and routes");
    let ramp_types = |v: &[(f64, String, String)]| {
        v.iter()
            .filter(|x| x.2 == "onramp")
            .map(|x| x.1.clone())
            .collect::<std::collections::BTreeSet<_>>()
    };
    assert_eq!(ramp_types(&none).into_iter().collect::<Vec<_>>(), ["human_ramp"]);
    assert_eq!(ramp_types(&all).into_iter().collect::<Vec<_>>(), ["ctrl"]);
}

#[test]
fn regression_fuzz_a_nan_begin_or_an_absurd_rate_is_refused_not_looped_on() {
    let (base, geometry) = i80();
    let text = std::fs::read_to_string(&base).unwrap();
    let dir = out_dir("fuzzed");
    std::fs::create_dir_all(&dir).unwrap();
    let spec = DemandSpec {
        scales: vec![1.0],
        ramp_share: None,
        controllable_shares: Vec::new(),
        mainline_share: None,
        seeds: vec![0],
        begin: 0.0,
        duration: 900.0,
        streams: Default::default(),
        loaded: Vec::new(),
    };
    for (from, to, needle) in [
        (
            "begin=\"0\"",
            "begin=\"NaN\"",
            "begin=\"NaN\" is not a non-negative number",
        ),
        (
            "vehsPerHour=\"1240\"",
            "vehsPerHour=\"1e300\"",
            "would give about",
        ),
    ] {
        let path = dir.join("base.rou.xml");
        std::fs::write(&path, text.replacen(from, to, 1)).unwrap();
        let err = generate(&path, std::slice::from_ref(&geometry), &spec, &dir.join("out")).unwrap_err();
        assert!(err.to_string().contains(needle), "{err}");
        assert!(!dir.join("out").exists(), "nothing written");
    }
}

#[test]
fn a_mainline_share_makes_freeway_vehicles_controllable_and_keeps_the_arrivals() {
    let (base, geometry) = i80();
    let out = out_dir("mainline");
    let spec = |share| DemandSpec {
        scales: vec![1.2],
        ramp_share: None,
        controllable_shares: vec![],
        mainline_share: share,
        seeds: vec![3],
        begin: 0.0,
        duration: 900.0,
        streams: Default::default(),
        loaded: Vec::new(),
    };
    let plain = generate(&base, std::slice::from_ref(&geometry), &spec(None), &out).unwrap();
    let mixed = generate(&base, std::slice::from_ref(&geometry), &spec(Some(0.3)), &out).unwrap();
    assert_eq!(mixed[0].file, "i80_d1.20_m0.30_s3.rou.xml");
    assert_eq!(mixed[0].mainline_share, Some(0.3));
    let (a, b) = (
        vehicles(&out.join(&plain[0].file)),
        vehicles(&out.join(&mixed[0].file)),
    );
    assert_eq!(a.len(), b.len());
    let mut freeway = 0;
    let mut ctrl = 0;
    for (x, y) in a.iter().zip(&b) {
        assert_eq!((x.0, &x.2), (y.0, &y.2), "same departures and routes");
        if y.2 == "freeway" {
            freeway += 1;
            assert_eq!(x.1, "human");
            ctrl += usize::from(y.1 == "ctrl");
        } else {
            assert_eq!(x.1, y.1, "ramp types are the base file's");
        }
    }
    // 30% of about 2,230 freeway vehicles (7,440 veh/h x 1.2 over 15 min); 4 standard deviations.
    let share = ctrl as f64 / freeway as f64;
    assert!(
        (share - 0.3).abs() < 4.0 * (0.3 * 0.7 / freeway as f64).sqrt(),
        "{share}"
    );
    // A file without a controllable vType takes a mainline share with `ctrl` as a copy of its
    // first passenger car's vType.
    let bare = out.join("bare.rou.xml");
    std::fs::write(
        &bare,
        r#"<routes><vType id="human" accel="2.1"/><route id="freeway" edges="approach main1"/><flow id="f" type="human" route="freeway" begin="0" end="600" vehsPerHour="600"/></routes>"#,
    )
    .unwrap();
    let made = generate(&bare, std::slice::from_ref(&geometry), &spec(Some(0.3)), &out).unwrap();
    assert_eq!(made[0].derived_type.as_deref(), Some("ctrl"));
    let text = std::fs::read_to_string(out.join(&made[0].file)).unwrap();
    assert!(text.contains(r#"<vType id="ctrl" accel="2.1"/>"#), "{text}");
    let drawn = vehicles(&out.join(&made[0].file));
    let ctrl = drawn.iter().filter(|v| v.1 == "ctrl").count();
    // 30% of about 120 vehicles; 4 standard deviations.
    assert!(
        (ctrl as f64 / drawn.len() as f64 - 0.3).abs() < 4.0 * (0.21 / drawn.len() as f64).sqrt(),
        "{ctrl} of {}",
        drawn.len()
    );
}

#[test]
fn each_stream_alone_keeps_its_vehicles_of_the_file_of_all_flows() {
    let (base, geometry) = i80();
    let out = out_dir("streams");
    let spec = |streams| DemandSpec {
        scales: vec![1.2],
        ramp_share: None,
        controllable_shares: vec![0.3],
        mainline_share: Some(0.3),
        seeds: vec![5],
        begin: 0.0,
        duration: 300.0,
        streams,
        loaded: Vec::new(),
    };
    let write = |streams| generate(&base, std::slice::from_ref(&geometry), &spec(streams), &out).unwrap();
    let (all, ramp, freeway) = (write(Streams::All), write(Streams::Ramp), write(Streams::Freeway));
    assert_eq!(ramp[0].file, "i80_d1.20_m0.30_ramp_s5.rou.xml");
    assert_eq!(freeway[0].file, "i80_d1.20_m0.30_freeway_s5.rou.xml");
    assert_eq!(ramp[0].streams, Streams::Ramp);
    let every = vehicles(&out.join(&all[0].file));
    let (r, f) = (
        vehicles(&out.join(&ramp[0].file)),
        vehicles(&out.join(&freeway[0].file)),
    );
    // The ramp's file holds exactly the vehicles of the route "onramp", the freeway's the
    // others, each with its departure and type; together they are the whole file.
    let split = |onramp: bool| -> Vec<_> {
        every
            .iter()
            .filter(|v| (v.2 == "onramp") == onramp)
            .cloned()
            .collect()
    };
    assert_eq!(r, split(true));
    assert_eq!(f, split(false));
    assert!(!r.is_empty() && !f.is_empty());
    assert_eq!(r.len() + f.len(), all[0].vehicles);
    // A stream the file does not have is refused.
    let bare = out.join("bare.rou.xml");
    std::fs::write(
        &bare,
        r#"<routes><vType id="human"/><route id="freeway" edges="approach main1"/><flow id="f" type="human" route="freeway" begin="0" end="60" vehsPerHour="600"/></routes>"#,
    )
    .unwrap();
    // i80.rou.xml: the ramp's flow and six lanes' flows; the bare file: one freeway flow.
    assert_eq!(
        flows_by_stream(&base, &[], std::slice::from_ref(&geometry)).unwrap(),
        (1, 6)
    );
    assert_eq!(
        flows_by_stream(&bare, &[], std::slice::from_ref(&geometry)).unwrap(),
        (0, 1)
    );
    let mut only_ramp = spec(Streams::Ramp);
    only_ramp.mainline_share = None;
    let err = generate(&bare, std::slice::from_ref(&geometry), &only_ramp, &out).unwrap_err();
    assert!(
        err.to_string().contains("the base file has no ramp flow"),
        "{err}"
    );
}

#[test]
fn a_controllable_share_applies_to_a_ramp_flow_of_a_plain_type() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("sumo_nets/single_lane_merge");
    let (base, geometry) = (
        dir.join("merge.rou.xml"),
        MergeGeometry::load(&dir.join("merge.toml")).unwrap(),
    );
    let out = out_dir("plain-ctrl");
    let spec = |shares: Vec<f64>| DemandSpec {
        scales: vec![1.2],
        ramp_share: None,
        controllable_shares: shares,
        mainline_share: None,
        seeds: vec![1],
        begin: 0.0,
        duration: 300.0,
        streams: Streams::All,
        loaded: Vec::new(),
    };
    let files = |shares| generate(&base, std::slice::from_ref(&geometry), &spec(shares), &out).unwrap();
    let plain = vehicles(&out.join(&files(vec![])[0].file));
    let swept = files(vec![0.0, 0.3, 1.0]);
    let ramp_types = |k: usize| -> Vec<String> {
        let v = vehicles(&out.join(&swept[k].file));
        // The arrivals and routes are the file's without a share; only the ramp's types move.
        let key = |v: &[(f64, String, String)]| v.iter().map(|x| (x.0, x.2.clone())).collect::<Vec<_>>();
        assert_eq!(key(&v), key(&plain));
        v.into_iter().filter(|x| x.2 == "ramp").map(|x| x.1).collect()
    };
    let (none, some, all) = (ramp_types(0), ramp_types(1), ramp_types(2));
    // single_lane_merge's ramp flow is of type "ctrl"; its first other vType is "human".
    assert!(
        none.iter().all(|t| t == "human") && all.iter().all(|t| t == "ctrl"),
        "{none:?} {all:?}"
    );
    let n = some.len() as f64;
    let ctrl = some.iter().filter(|t| *t == "ctrl").count() as f64;
    // 360 veh/h over 300 s: about 30 ramp vehicles; 4 standard deviations of 30%.
    assert!((ctrl / n - 0.3).abs() < 4.0 * (0.21 / n).sqrt(), "{ctrl} of {n}");
    // A ramp flow of a plain other type takes the controllable type with the share.
    let human_ramp = out.join("human_ramp.rou.xml");
    let text = std::fs::read_to_string(&base).unwrap();
    std::fs::write(
        &human_ramp,
        text.replace(
            r#"<flow id="onramp" type="ctrl""#,
            r#"<flow id="onramp" type="human""#,
        ),
    )
    .unwrap();
    let m = generate(
        &human_ramp,
        std::slice::from_ref(&geometry),
        &spec(vec![0.3]),
        &out,
    )
    .unwrap();
    let v = vehicles(&out.join(&m[0].file));
    let ramp: Vec<&(f64, String, String)> = v.iter().filter(|x| x.2 == "ramp").collect();
    let ctrl = ramp.iter().filter(|x| x.1 == "ctrl").count() as f64;
    let n = ramp.len() as f64;
    assert!((ctrl / n - 0.3).abs() < 4.0 * (0.21 / n).sqrt(), "{ctrl} of {n}");
    assert!(v.iter().filter(|x| x.2 == "main").all(|x| x.1 == "human"));
    // Without a vType of another type, the share has nothing to give the others.
    let bare = out.join("bare.rou.xml");
    std::fs::write(
        &bare,
        r#"<routes><vType id="ctrl"/><route id="r" edges="ramp merge out"/><flow id="onramp" type="ctrl" route="r" begin="0" end="60" vehsPerHour="600"/></routes>"#,
    )
    .unwrap();
    let err = generate(&bare, std::slice::from_ref(&geometry), &spec(vec![0.5]), &out).unwrap_err();
    assert!(
        err.to_string()
            .contains("`onramp` is of the controllable type `ctrl`"),
        "{err}"
    );
}

#[test]
fn explicit_vehicles_and_trips_are_kept_copied_by_the_scale_and_take_the_shares() {
    let (_, geometry) = i80();
    let out = out_dir("explicit");
    std::fs::create_dir_all(&out).unwrap();
    let base = out.join("explicit.rou.xml");
    std::fs::write(
        &base,
        r#"<routes>
    <vType id="human"/>
    <vType id="ctrl"/>
    <route id="freeway" edges="approach main1 merge main2 departure"/>
    <vehicle id="a" type="human" route="freeway" depart="1.50" departLane="2"/>
    <trip id="b" type="ctrl" depart="3" from="ramp" to="departure"/>
    <vehicle id="c" depart="7.25"><route edges="ramp merge main2 departure"/><param key="k" value="v"/></vehicle>
    <vehicle id="late" type="human" route="freeway" depart="900"/>
</routes>"#,
    )
    .unwrap();
    let merges = std::slice::from_ref(&geometry);
    let spec = |scale: f64, streams, shares: Vec<f64>, mainline| DemandSpec {
        scales: vec![scale],
        ramp_share: None,
        controllable_shares: shares,
        mainline_share: mainline,
        seeds: vec![0],
        begin: 0.0,
        duration: 600.0,
        streams,
        loaded: Vec::new(),
    };
    // (tag, id, type, depart, the rest of the element) of every vehicle of a generated file.
    let read = |spec: DemandSpec| -> Vec<(String, String, String, String, String)> {
        let m = generate(&base, merges, &spec, &out).unwrap();
        let text = std::fs::read_to_string(out.join(&m[0].file)).unwrap();
        let doc = roxmltree::Document::parse(&text).unwrap();
        doc.root_element()
            .children()
            .filter(|n| n.has_tag_name("vehicle") || n.has_tag_name("trip"))
            .map(|n| {
                let rest: Vec<String> = n
                    .attributes()
                    .filter(|a| !["id", "type", "depart"].contains(&a.name()))
                    .map(|a| format!("{}={}", a.name(), a.value()))
                    .chain(n.descendants().skip(1).filter(|c| c.is_element()).map(|c| {
                        let attrs: Vec<String> = c.attributes().map(|a| a.value().to_owned()).collect();
                        format!("<{} {}>", c.tag_name().name(), attrs.join(" "))
                    }))
                    .collect();
                let a = |k: &str| n.attribute(k).unwrap().to_owned();
                (
                    n.tag_name().name().to_owned(),
                    a("id"),
                    a("type"),
                    a("depart"),
                    rest.join(" "),
                )
            })
            .collect()
    };
    let row = |tag: &str, id: &str, vtype: &str, depart: &str, rest: &str| {
        (tag.into(), id.into(), vtype.into(), depart.into(), rest.into())
    };
    let c_rest = "<route ramp merge main2 departure> <param k v>";
    // Scale 1: every vehicle that departs within the 600 s, as written (c's route and parameter
    // too); `late` departs after them.
    assert_eq!(
        read(spec(1.0, Streams::All, vec![], None)),
        vec![
            row("vehicle", "a", "human", "1.50", "route=freeway departLane=2"),
            row("trip", "b", "ctrl", "3", "from=ramp to=departure"),
            row("vehicle", "c", "DEFAULT_VEHTYPE", "7.25", c_rest),
        ]
    );
    // Scale 2: each twice, at its departure.
    let ids: Vec<String> = read(spec(2.0, Streams::All, vec![], None))
        .into_iter()
        .map(|v| v.1)
        .collect();
    assert_eq!(ids, ["a", "a#1", "b", "b#1", "c", "c#1"]);
    // The ramp's alone: b (from the ramp's edge) and c (its route starts there).
    let ramp: Vec<String> = read(spec(1.0, Streams::Ramp, vec![], None))
        .into_iter()
        .map(|v| v.1)
        .collect();
    assert_eq!(ramp, ["b", "c"]);
    // A controllable share of 0 leaves the ramp's b to SUMO as the first other vType; a
    // mainline share of 1 makes the freeway's a controllable.
    let types: Vec<String> = read(spec(1.0, Streams::All, vec![0.0], Some(1.0)))
        .into_iter()
        .map(|v| v.2)
        .collect();
    assert_eq!(types, ["ctrl", "human", "DEFAULT_VEHTYPE"]);
    // A share of 1 makes every ramp vehicle controllable, c of a plain other type too.
    let types: Vec<String> = read(spec(1.0, Streams::All, vec![1.0], Some(0.0)))
        .into_iter()
        .map(|v| v.2)
        .collect();
    assert_eq!(types, ["human", "ctrl", "ctrl"]);
    assert_eq!(flows_by_stream(&base, &[], merges).unwrap(), (2, 2));
    // Scale 0.5 over 400 vehicles keeps about half (4 standard deviations of 10).
    let many: String = (0..400)
        .map(|k| format!("<vehicle id=\"v{k}\" type=\"human\" route=\"freeway\" depart=\"{k}\"/>"))
        .collect();
    std::fs::write(
        &base,
        format!(r#"<routes><vType id="human"/><route id="freeway" edges="approach main1"/>{many}</routes>"#),
    )
    .unwrap();
    let mut long = spec(0.5, Streams::All, vec![], None);
    long.duration = 1000.0;
    let kept = read(long).len();
    assert!((160..=240).contains(&kept), "{kept}");
    // A departure that is not a time is refused.
    std::fs::write(
        &base,
        r#"<routes><vType id="human"/><trip id="t" depart="triggered" from="ramp" to="departure"/></routes>"#,
    )
    .unwrap();
    let err = generate(&base, merges, &spec(1.0, Streams::All, vec![], None), &out).unwrap_err();
    assert!(
        err.to_string()
            .contains("depart=\"triggered\" is not a time in seconds"),
        "{err}"
    );
}

#[test]
fn flows_with_a_route_in_them_poisson_periods_and_sumos_default_interval_are_generated() {
    let (_, geometry) = i80();
    let out = out_dir("flow-forms");
    std::fs::create_dir_all(&out).unwrap();
    let base = out.join("forms.rou.xml");
    // As SUMO's documentation writes flows: a route (and parameters) in the flow, Poisson
    // arrivals by `period="exp(r)"`, and no `begin` or `end` (0 to 24 hours).
    std::fs::write(
        &base,
        r#"<routes>
    <vType id="human"/>
    <vType id="ctrl"/>
    <flow id="main" type="human" period="exp(2)" departLane="best">
        <route edges="approach main1 merge main2 departure"/>
    </flow>
    <flow id="onramp" type="human" end="300" vehsPerHour="720">
        <route edges="ramp merge main2 departure"/><param key="k" value="v"/>
    </flow>
</routes>"#,
    )
    .unwrap();
    let spec = DemandSpec {
        scales: vec![1.0],
        ramp_share: None,
        controllable_shares: vec![1.0],
        mainline_share: None,
        seeds: vec![0],
        begin: 0.0,
        duration: 600.0,
        streams: Streams::All,
        loaded: Vec::new(),
    };
    let m = generate(&base, std::slice::from_ref(&geometry), &spec, &out).unwrap();
    let text = std::fs::read_to_string(out.join(&m[0].file)).unwrap();
    let doc = roxmltree::Document::parse(&text).unwrap();
    let of = |prefix: &str| -> Vec<roxmltree::Node> {
        doc.root_element()
            .children()
            .filter(|n| n.has_tag_name("vehicle") && n.attribute("id").unwrap().starts_with(prefix))
            .collect()
    };
    let (main, ramp) = (of("main."), of("onramp."));
    // 2 per second over the run's 600 s, 720 veh/h over the flow's 300 s; 4 standard deviations.
    for (n, mean) in [(main.len(), 1200.0), (ramp.len(), 60.0)] {
        assert!(
            (n as f64 - mean).abs() < 4.0 * f64::sqrt(mean),
            "{n} vehicles, mean {mean}"
        );
    }
    let last = |v: &[roxmltree::Node]| {
        v.last()
            .unwrap()
            .attribute("depart")
            .unwrap()
            .parse::<f64>()
            .unwrap()
    };
    assert!(last(&main) > 590.0 && last(&ramp) < 300.0);
    // Each vehicle keeps its flow's route and parameters; the ramp's (every ramp vehicle
    // controllable) are told from the freeway's by the route in them.
    let route = |n: &roxmltree::Node| {
        n.children()
            .find(|c| c.has_tag_name("route"))
            .unwrap()
            .attribute("edges")
            .unwrap()
            .to_owned()
    };
    assert!(
        main.iter()
            .all(|n| route(n).starts_with("approach") && n.attribute("type") == Some("human"))
    );
    assert!(
        ramp.iter()
            .all(|n| route(n).starts_with("ramp") && n.attribute("type") == Some("ctrl"))
    );
    assert!(ramp.iter().all(|n| n.children().any(|c| c.has_tag_name("param"))));
    // A rate that is not a number is named as written.
    let text = std::fs::read_to_string(&base).unwrap();
    std::fs::write(&base, text.replace("exp(2)", "exp(fast)")).unwrap();
    let err = generate(&base, std::slice::from_ref(&geometry), &spec, &out).unwrap_err();
    assert!(err.to_string().contains("period=\"exp(fast)\""), "{err}");
}

/// The top-level elements of route file `path` as written, split in two: those whose tag
/// `first` picks, and the rest.
fn split_elements(path: &Path, first: impl Fn(&str) -> bool) -> (String, String) {
    let text = std::fs::read_to_string(path).unwrap();
    let doc = roxmltree::Document::parse(&text).unwrap();
    let (mut picked, mut rest) = (String::new(), String::new());
    for node in doc.root_element().children().filter(|n| n.is_element()) {
        let part = if first(node.tag_name().name()) {
            &mut picked
        } else {
            &mut rest
        };
        *part += &text[node.range()];
    }
    (picked, rest)
}

#[test]
fn route_files_that_split_types_and_flows_are_one_demand() {
    // The bundled I-80 routes split in two, as configurations with a types file and a flows file
    // do: the types alone have nothing to scale; both together give the same vehicles as the
    // file they came from.
    let (base, geometry) = i80();
    let out = out_dir("split");
    let (types, rest) = split_elements(&base, |tag| tag.starts_with("vType"));
    std::fs::create_dir_all(&out).unwrap();
    let (a, b) = (out.join("types.rou.xml"), out.join("flows.rou.xml"));
    std::fs::write(&a, format!("<routes>{types}</routes>")).unwrap();
    std::fs::write(&b, format!("<routes>\n<!-- flows -->\n{rest}</routes>")).unwrap();
    let spec = DemandSpec {
        scales: vec![1.0],
        ramp_share: None,
        controllable_shares: vec![0.3],
        mainline_share: Some(0.3),
        seeds: vec![4],
        begin: 0.0,
        duration: 300.0,
        streams: Streams::All,
        loaded: Vec::new(),
    };
    let merges = std::slice::from_ref(&geometry);
    let err = generate(&a, merges, &spec, &out).unwrap_err();
    assert!(
        err.to_string()
            .contains("no <flow>, <vehicle> or <trip> to scale"),
        "{err}"
    );
    let both = out.join("both.rou.xml");
    std::fs::write(&both, combined_route_files(&[a, b]).unwrap()).unwrap();
    let whole = generate(&base, merges, &spec, &out).unwrap();
    let split = generate(&both, merges, &spec, &out).unwrap();
    assert_eq!(
        vehicles(&out.join(&whole[0].file)),
        vehicles(&out.join(&split[0].file))
    );
}

#[test]
fn departures_start_at_the_begin_of_the_configuration_that_runs_them() {
    // The I-80 base file with its flows an hour later (3,600-4,500 s), as public scenarios set
    // their flows at the hour they model: a window from 3,600 s gives the vehicles of the window
    // from 0 of the file as it is, an hour later; one from 0 s over 300 s gives none.
    let (base, geometry) = i80();
    let out = out_dir("begin");
    std::fs::create_dir_all(&out).unwrap();
    let later = out.join("later.rou.xml");
    let text = std::fs::read_to_string(&base).unwrap();
    std::fs::write(
        &later,
        text.replace(r#"begin="0" end="900""#, r#"begin="3600" end="4500""#),
    )
    .unwrap();
    let spec = |begin: f64| DemandSpec {
        scales: vec![1.2],
        ramp_share: None,
        controllable_shares: vec![0.3],
        mainline_share: Some(0.3),
        seeds: vec![2],
        begin,
        duration: 300.0,
        streams: Streams::All,
        loaded: Vec::new(),
    };
    let merges = std::slice::from_ref(&geometry);
    let now = vehicles(&out.join(&generate(&base, merges, &spec(0.0), &out).unwrap()[0].file));
    let then = vehicles(&out.join(&generate(&later, merges, &spec(3600.0), &out).unwrap()[0].file));
    assert!(now.len() > 400, "{} vehicles", now.len());
    assert_eq!(now.len(), then.len());
    for ((t0, type0, route0), (t1, type1, route1)) in now.iter().zip(&then) {
        assert!((t1 - t0 - 3600.0).abs() < 0.011, "{t0} -> {t1}");
        assert_eq!((type0, route0), (type1, route1));
    }
    let err = generate(&later, merges, &spec(0.0), &out).unwrap_err();
    assert!(err.to_string().contains("departs between 0 and 300 s"), "{err}");
}

#[test]
fn types_and_routes_of_the_additional_files_count_and_are_not_written_again() {
    // The bundled I-80 routes with their types and routes in an additional file, as many
    // public scenarios keep them: the flows alone give the vehicles of the whole file, and the
    // generated file defines no type or route SUMO already loads (it refuses one defined twice).
    let (base, geometry) = i80();
    let out = out_dir("additional");
    let (defs, flows) = split_elements(&base, |tag| tag.starts_with("vType") || tag.starts_with("route"));
    assert!(!defs.is_empty() && !flows.is_empty());
    std::fs::create_dir_all(&out).unwrap();
    let (add, only_flows) = (out.join("types.add.xml"), out.join("flows.rou.xml"));
    std::fs::write(
        &add,
        format!("<additional>{defs}<e1Detector id=\"d\"/></additional>"),
    )
    .unwrap();
    std::fs::write(&only_flows, format!("<routes>{flows}</routes>")).unwrap();
    let spec = |loaded: Vec<PathBuf>| DemandSpec {
        scales: vec![1.2],
        ramp_share: None,
        controllable_shares: vec![0.3],
        mainline_share: Some(0.3),
        seeds: vec![3],
        begin: 0.0,
        duration: 300.0,
        streams: Streams::All,
        loaded,
    };
    let merges = std::slice::from_ref(&geometry);
    // Without the additional file the flows' routes are undefined.
    let err = generate(&only_flows, merges, &spec(Vec::new()), &out).unwrap_err();
    assert!(err.to_string().contains("not defined before it"), "{err}");
    let whole = generate(&base, merges, &spec(Vec::new()), &out).unwrap();
    let whole = vehicles(&out.join(&whole[0].file));
    let split = generate(&only_flows, merges, &spec(vec![add]), &out).unwrap();
    let written = std::fs::read_to_string(out.join(&split[0].file)).unwrap();
    assert_eq!(vehicles(&out.join(&split[0].file)), whole);
    assert!(
        whole.len() > 400 && whole.iter().any(|v| v.1 == "ctrl"),
        "{} vehicles",
        whole.len()
    );
    assert!(
        !written.contains("<vType") && !written.contains("<route "),
        "{written:.300}"
    );
}
