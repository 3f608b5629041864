use super::*;

const WPL: &str = "QGC WPL 110\n\
0\t1\t0\t16\t0\t0\t0\t0\t40.4400\t-79.9400\t300.0\t1\n\
1\t0\t3\t22\t0\t0\t0\t0\t0\t0\t25\t1\n\
2\t0\t3\t178\t1\t8\t-1\t0\t0\t0\t0\t1\n\
3\t0\t3\t16\t5\t0\t0\t0\t40.4410\t-79.9400\t25\t1\n\
4\t0\t0\t19\t10\t0\t0\t0\t40.4410\t-79.9390\t350\t1\n\
5\t0\t3\t206\t25\t0\t1\t0\t0\t0\t0\t1\n\
6\t0\t10\t16\t0\t0\t0\t0\t40.4400\t-79.9390\t30\t1\n\
7\t0\t3\t20\t0\t0\t0\t0\t0\t0\t0\t1\n";

#[test]
fn waypoints_file_reads_home_items_frames_and_not_modelled() {
    let p = parse_waypoints(WPL, "t.waypoints").unwrap();
    assert_eq!(
        p.home,
        GeoPoint {
            lat_deg: 40.44,
            lon_deg: -79.94,
            alt_m: 300.0
        }
    );
    assert_eq!(p.items.len(), 7, "row 0 is home, every other row an item");
    assert_eq!(p.items[0].kind, ItemKind::Takeoff { alt_m: 25.0 });
    assert_eq!(p.items[1].kind, ItemKind::ChangeSpeed { speed_m_s: 8.0 });
    assert_eq!(p.items[2].kind, ItemKind::Waypoint { hold_s: 5.0 });
    // absolute 350 m AMSL over a 300 m home = 50 m above home
    assert_eq!(p.items[3].kind, ItemKind::LoiterTime { time_s: 10.0 });
    assert_eq!(p.items[3].frame, AltFrame::Absolute);
    assert!((p.items[3].position.unwrap().alt_m - 50.0).abs() < 1e-9);
    // DO_SET_CAM_TRIGG_DIST: kept, listed, flies nothing
    assert_eq!(
        p.items[4].kind,
        ItemKind::NotModelled {
            command: 206,
            flown_through: false
        }
    );
    assert_eq!(p.not_modelled().len(), 1);
    assert_eq!(p.items[5].frame, AltFrame::Terrain);
    assert_eq!(p.terrain_items().len(), 1);
    assert_eq!(p.items[6].kind, ItemKind::ReturnToLaunch);
    assert_eq!(p.items[6].origin, "line 9");
}

#[test]
fn vtol_commands_and_loiter_turns_are_kept_with_their_parameters() {
    let text = "QGC WPL 110\n\
0\t1\t0\t16\t0\t0\t0\t0\t40.4400\t-79.9400\t300.0\t1\n\
1\t0\t3\t84\t0\t0\t0\t0\t0\t0\t30\t1\n\
2\t0\t2\t3000\t4\t0\t0\t0\t0\t0\t0\t1\n\
3\t0\t3\t18\t3\t0\t-120\t0\t40.4410\t-79.9400\t50\t1\n\
4\t0\t3\t17\t0\t0\t0\t0\t40.4420\t-79.9400\t50\t1\n\
5\t0\t2\t3000\t3\t0\t0\t0\t0\t0\t0\t1\n\
6\t0\t3\t85\t0\t0\t0\t0\t0\t0\t0\t1\n";
    let p = parse_waypoints(text, "vtol.waypoints").unwrap();
    let kinds: Vec<ItemKind> = p.items.iter().map(|i| i.kind).collect();
    assert_eq!(
        kinds,
        [
            ItemKind::VtolTakeoff { alt_m: 30.0 },
            ItemKind::VtolTransition { to_fw: true },
            ItemKind::LoiterTurns { turns: 3.0 },
            ItemKind::LoiterUnlimited,
            ItemKind::VtolTransition { to_fw: false },
            ItemKind::VtolLand,
        ]
    );
    assert_eq!(
        p.items[2].loiter_radius_m,
        Some(120.0),
        "the radius, unsigned"
    );
    assert_eq!(p.items[0].position, None, "VTOL_TAKEOFF at 0, 0: here");
    assert!(p.not_modelled().is_empty(), "84, 85 and 3000 are modelled");
    // and back through the protocol's items
    let items = p.to_mission_items();
    assert_eq!(
        (items[1].command, items[2].params[0], items[3].params[2]),
        (84, 4.0, 120.0)
    );
}

fn bad(text: &str) -> String {
    parse_waypoints(text, "bad.waypoints")
        .unwrap_err()
        .to_string()
}

#[test]
fn bad_waypoints_files_name_the_item_and_why() {
    let home = "QGC WPL 110\n0\t1\t0\t16\t0\t0\t0\t0\t40.44\t-79.94\t300\t1\n";
    // each bad row names its item and line, and why
    for (row, why) in [
        (
            "9999\t0\t0\t0\t0\t40.44\t-79.94\t25",
            "command 9999 is not a MAV_CMD",
        ),
        (
            "16\t0\t0\t0\t0\t95.0\t-79.94\t25",
            "latitude 95 is out of range",
        ),
        (
            "16\t0\t0\t0\t0\t40.0\t-190\t25",
            "longitude -190 is out of range",
        ),
        ("16\t0\t0\t0\t0\tNaN\t-79.94\t25", "not finite"),
        (
            "16\t0\t0\t0\t0\tabc\t-79.94\t25",
            "latitude \"abc\" is not a number",
        ),
        (
            "3000\t2\t0\t0\t0\t0\t0\t0",
            "must be 3 (MAV_VTOL_STATE_MC) or 4",
        ),
    ] {
        let e = bad(&format!("{home}1\t0\t3\t{row}\t1\n"));
        assert!(
            e.contains("bad.waypoints") && e.contains("line 3") && e.contains(why),
            "{e}"
        );
    }
    let e = bad(home);
    assert!(e.contains("no mission items"), "{e}");
    let e = bad("");
    assert!(e.contains("empty file"), "{e}");
    let e = bad("QGC WPL 120\n");
    assert!(e.contains("line 1") && e.contains("QGC WPL 110"), "{e}");
    let e = bad(&format!("{home}1\t0\t3\t16\t0\t0\n"));
    assert!(e.contains("line 3") && e.contains("expected 12"), "{e}");
}

#[test]
fn a_mission_list_with_ardupilots_home_item_becomes_a_plan_that_returns_home() {
    let p = parse_waypoints(WPL, "t.waypoints").unwrap();
    // round trip through the protocol's items (home first), minus its RTL
    let mut items = p.to_mission_items();
    assert_eq!(items.len(), p.items.len() + 1);
    assert_eq!(
        (items[0].lat_deg, items[0].alt_m, items[0].frame),
        (40.44, 300.0, 0)
    );
    items.pop();
    let m = crate::mission::protocol::Mission {
        items,
        mission_id: 7,
        origin: crate::mission::protocol::Origin::Downloaded,
        home_is_item0: true,
    };
    let (back, offset) = Plan::from_mission("vehicle", &m, None).unwrap();
    assert_eq!(offset, 1);
    assert_eq!(back.home, p.home);
    assert_eq!(
        back.items.len(),
        p.items.len(),
        "the RTL it lost is added back"
    );
    assert_eq!(back.items.last().unwrap().kind, ItemKind::ReturnToLaunch);
    assert_eq!(back.items.last().unwrap().origin, "added: return and land");
    for (a, b) in p.items.iter().zip(&back.items).take(p.items.len() - 1) {
        assert_eq!(a.kind, b.kind, "{} vs {}", a.origin, b.origin);
        let (pa, pb) = (
            a.position.map(|q| (q.lat_deg, q.lon_deg)),
            b.position.map(|q| (q.lat_deg, q.lon_deg)),
        );
        assert_eq!(pa, pb);
    }
    assert_eq!(
        back.not_modelled().len(),
        1,
        "the DO_ command is kept and listed"
    );
    // a bad item names its seq; no home item and no home heard: an error
    let mut bad = m.clone();
    bad.items[3].lat_deg = 95.0;
    let e = Plan::from_mission("vehicle", &bad, None)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("item 2 (seq 3)") && e.contains("latitude 95"),
        "{e}"
    );
    let px4 = crate::mission::protocol::Mission {
        home_is_item0: false,
        ..m
    };
    let e = Plan::from_mission("vehicle", &px4, None)
        .unwrap_err()
        .to_string();
    assert!(e.contains("no home"), "{e}");
    let (flown, offset) = Plan::from_mission("vehicle", &px4, Some(p.home)).unwrap();
    assert_eq!(
        (offset, flown.items[0].command),
        (0, 16),
        "without a home item, item 0 is flown"
    );
}

const PLAN: &str = r#"{
      "fileType": "Plan", "groundStation": "QGroundControl", "version": 1,
      "geoFence": {"circles": [], "polygons": [], "version": 2},
      "rallyPoints": {"points": [], "version": 2},
      "mission": {
        "cruiseSpeed": 15, "firmwareType": 3, "globalPlanAltitudeMode": 1, "hoverSpeed": 6,
        "plannedHomePosition": [47.3977419, 8.545594, 487.989], "vehicleType": 2, "version": 2,
        "items": [
          {"AMSLAltAboveTerrain": null, "Altitude": 30, "AltitudeMode": 1, "autoContinue": true,
           "command": 22, "doJumpId": 1, "frame": 3, "params": [15, 0, 0, null, 47.3977419, 8.545594, 30],
           "type": "SimpleItem"},
          {"autoContinue": true, "command": 16, "doJumpId": 2, "frame": 3,
           "params": [3, 0, 0, null, 47.3985, 8.5456, 30], "type": "SimpleItem"},
          {"type": "ComplexItem", "complexItemType": "survey", "version": 5, "angle": 0,
           "polygon": [[47.398, 8.546], [47.398, 8.547], [47.399, 8.547]],
           "TransectStyleComplexItem": {
             "CameraCalc": {"DistanceToSurface": 40, "version": 2},
             "Items": [
               {"autoContinue": true, "command": 16, "doJumpId": 3, "frame": 3, "params": [0, 0, 0, null, 47.3981, 8.5461, 40], "type": "SimpleItem"},
               {"autoContinue": true, "command": 206, "doJumpId": 4, "frame": 2, "params": [25, 0, 1, 0, 0, 0, 0], "type": "SimpleItem"},
               {"autoContinue": true, "command": 16, "doJumpId": 5, "frame": 3, "params": [0, 0, 0, null, 47.3989, 8.5469, 40], "type": "SimpleItem"}
             ],
             "VisualTransectPoints": [[47.3981, 8.5461], [47.3989, 8.5469]]
           }},
          {"type": "ComplexItem", "complexItemType": "CorridorScan", "Altitude": 35,
           "TransectStyleComplexItem": {"VisualTransectPoints": [[47.3990, 8.5470], [47.3995, 8.5470]]}},
          {"autoContinue": true, "command": 20, "doJumpId": 9, "frame": 2, "params": [0, 0, 0, 0, 0, 0, 0], "type": "SimpleItem"}
        ]
      }
    }"#;

#[test]
fn qgc_plan_reads_simple_and_complex_items_home_and_speeds() {
    let p = parse_qgc_plan(PLAN, "t.plan").unwrap();
    assert_eq!(p.home.alt_m, 487.989);
    assert_eq!(p.hover_speed_m_s, Some(6.0));
    assert_eq!(p.cruise_speed_m_s, Some(15.0));
    let cmds: Vec<u16> = p.items.iter().map(|i| i.command).collect();
    assert_eq!(
        cmds,
        [22, 16, 16, 206, 16, 16, 16, 20],
        "survey Items expanded; corridor from VisualTransectPoints"
    );
    assert_eq!(p.items[1].kind, ItemKind::Waypoint { hold_s: 3.0 });
    assert_eq!(
        p.items[2].origin,
        "mission.items[2].TransectStyleComplexItem.Items[0]"
    );
    assert_eq!(p.items[2].position.unwrap().alt_m, 40.0);
    assert_eq!(
        p.items[5].position.unwrap().alt_m,
        35.0,
        "corridor points at the item's Altitude"
    );
    assert_eq!(p.not_modelled().len(), 1);
}

#[test]
fn bad_qgc_plans_name_the_item_and_why() {
    let e = parse_qgc_plan("{\"fileType\": \"Plan\", ", "x.plan")
        .unwrap_err()
        .to_string();
    assert!(e.contains("x.plan") && e.contains("malformed JSON"), "{e}");
    let e = parse_qgc_plan(
        &PLAN.replace(
            "\"command\": 16, \"doJumpId\": 2",
            "\"command\": 31337, \"doJumpId\": 2",
        ),
        "x.plan",
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("item 1 (mission.items[1])") && e.contains("31337 is not a MAV_CMD"),
        "{e}"
    );
    let e = parse_qgc_plan(&PLAN.replace("47.3985, 8.5456", "47.3985, 181.0"), "x.plan")
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("mission.items[1]") && e.contains("longitude 181 is out of range"),
        "{e}"
    );
    let p = parse_qgc_plan(
        &PLAN.replace("[47.3981, 8.5461], [47.3989", "[97.3981, 8.5461], [47.3989"),
        "x.plan",
    );
    assert_eq!(
        p.map(|p| p.items.len()).ok(),
        Some(8),
        "the saved Items win over the drawing"
    );
    let e = parse_qgc_plan(
        r#"{"fileType": "Plan", "mission": {"items": []}}"#,
        "x.plan",
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("no mission items"), "{e}");
    let e = parse_qgc_plan(r#"{"fileType": "Plan", "mission": {"items": [{"type": "SimpleItem", "command": 16, "frame": 3, "params": [0, 0, 0]}]}}"#, "x.plan").unwrap_err().to_string();
    assert!(
        e.contains("mission.items[0]") && e.contains("expected 7"),
        "{e}"
    );
}
