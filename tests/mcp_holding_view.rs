//! What the camera sees while the gripper holds an object (the long session's stuck pencil,
//! seed 3): the held pencil hangs in the wrist camera's view and hides the near part of the
//! blue square, which was then reported 4 mm off; the spot a failure reply suggested (planned
//! from the view before the pick) was refused by the next place (planned from a view while
//! holding), and a spot planned beside a half-hidden object could run the pencil into it.

mod common;
#[path = "common/lab.rs"]
mod lab;

use lab::{assert_near, lab, runtime, scene};
use serde_json::json;

#[test]
fn objects_half_hidden_by_the_held_pencil_stay_where_they_were_seen() {
    runtime().block_on(async {
        let lab = lab(Some(scene("behind_the_pencil.toml"))).await;
        let before = lab.seen().await;
        let at = |label: &str| before.iter().find(|s| s.0 == label).unwrap().1;
        let square = at("blue square");
        let truth = lab.truth_of("blue square").await;
        assert_near(&truth, square, 0.0015);
        lab.ok(
            "pick_object",
            json!({"object_name": "pencil", "pick_coordinate": at("pencil")}),
        )
        .await;
        // Refused while holding; the reply suggests where to put the pencil down.
        let (text, _) = lab
            .call(
                "move2by",
                json!({"object_name": "blue square", "pick_coordinate": square,
                       "direction": "up", "distance": 0.04}),
            )
            .await;
        assert!(text.contains("'pencil' is still held"), "{text}");
        let suggested: Vec<f64> = text
            .rsplit_once("e.g. at [")
            .and_then(|(_, p)| p.strip_suffix(']'))
            .unwrap()
            .split(", ")
            .map(|v| v.parse().unwrap())
            .collect();
        let holding = lab.seen().await;
        assert_eq!(holding.len(), 2, "{holding:?}");
        let seen = holding.iter().find(|s| s.0 == "blue square").unwrap().1;
        let off = (seen[0] - square[0]).hypot(seen[1] - square[1]);
        assert!(
            off < 0.001,
            "while holding the pencil the blue square is seen at {seen:?}, {:.1} mm from \
             {square:?} where it was seen before (and is)",
            off * 1000.0
        );
        lab.ok("place_object", json!({"place_coordinate": suggested}))
            .await;
        assert_near(
            &lab.truth_of("pencil").await,
            [suggested[0], suggested[1]],
            0.006,
        );
    });
}
