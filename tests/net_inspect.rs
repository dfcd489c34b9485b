//! `mpgdrive net inspect`: the merges of the bundled networks are found with the lanes their
//! hand-written merge.toml names, and the proposed merge.toml is valid for its network.

mod common;

use common::{bin, fresh_dir};
use mpgdrive::sumo::MergeGeometry;
use mpgdrive::sumo::inputs::check_geometry;
use mpgdrive::sumo::inspect::{BEFORE_END, LANE_MARGIN, PICK_UP, find_merges, proposal};
use std::path::Path;

#[test]
fn the_bundled_merges_are_found_and_the_proposals_fit_their_networks() {
    let dir = fresh_dir("net-inspect");
    for (net, merge, lane_end) in [
        (
            "sumo_nets/i80_merge/i80.net.xml",
            "sumo_nets/i80_merge/merge.toml",
            422.0,
        ),
        (
            "sumo_nets/single_lane_merge/merge.net.xml",
            "sumo_nets/single_lane_merge/merge.toml",
            400.0,
        ),
        // Along the lanes: fw_in (398.5 m), the 3 m junction lane, accel (114.5 m).
        (
            "sumo_nets/curved_ramp_merge/curved.net.xml",
            "sumo_nets/curved_ramp_merge/merge.toml",
            516.0,
        ),
    ] {
        let net = Path::new(env!("CARGO_MANIFEST_DIR")).join(net);
        let bundled = MergeGeometry::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join(merge)).unwrap();
        let merges = find_merges(&net).unwrap();
        assert_eq!(merges.len(), 1, "{}", net.display());
        let m = &merges[0];
        assert_eq!(m.ramp_lanes, bundled.ramp_lanes);
        assert_eq!(m.target_lanes, bundled.target_lanes);
        let beside = bundled.merge_lane(bundled.ramp_lanes.last().unwrap()).unwrap().0;
        assert_eq!(m.target_lane, beside);
        assert!(
            (m.lane_end - lane_end).abs() < 1e-9,
            "{} ends at {}",
            m.target_lane,
            m.lane_end
        );
        let path = dir.join("proposed.toml");
        std::fs::write(&path, proposal(m, &net)).unwrap();
        let proposed = MergeGeometry::load(&path).unwrap();
        assert!((proposed.conflict_point - (lane_end - BEFORE_END)).abs() < 1e-9);
        // 120 m before the lane's end, or 10 m before the acceleration lane when that is
        // earlier (the curved network's 114.5 m lane).
        let control_from = (lane_end - PICK_UP).min(m.lane_start - LANE_MARGIN);
        assert!(
            (proposed.control_from - control_from).abs() < 0.06,
            "{}",
            proposed.control_from
        );
        // The bundled merge.toml of the curved network is the proposal.
        if bundled.target_start == 0.0 {
            assert_eq!(
                (bundled.conflict_point, bundled.control_from, bundled.merge_from),
                (
                    proposed.conflict_point,
                    proposed.control_from,
                    proposed.merge_from
                )
            );
        }
        check_geometry(&proposed, &path, &net).unwrap();
    }
}

#[test]
fn net_inspect_writes_a_proposal_and_refuses_a_network_without_a_merge() {
    let dir = fresh_dir("net-inspect-cli");
    let out = bin()
        .args([
            "net",
            "inspect",
            "sumo_nets/single_lane_merge/merge.net.xml",
            "--out",
        ])
        .arg(dir.join("merge.toml"))
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(MergeGeometry::load(&dir.join("merge.toml")).is_ok());
    // A straight road: every lane goes on.
    let net = "<net><edge id=\"a\" from=\"n0\" to=\"n1\"><lane id=\"a_0\" index=\"0\" shape=\"0,0 100,0\"/></edge>\
               <edge id=\"b\" from=\"n1\" to=\"n2\"><lane id=\"b_0\" index=\"0\" shape=\"100,0 200,0\"/></edge>\
               <connection from=\"a\" to=\"b\" fromLane=\"0\" toLane=\"0\"/></net>\n";
    std::fs::write(dir.join("straight.net.xml"), net).unwrap();
    let out = bin()
        .args(["net", "inspect"])
        .arg(dir.join("straight.net.xml"))
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("no merge found"));
}
