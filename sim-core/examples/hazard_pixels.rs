//! How many pixels of the front camera a hazard's object covers at 20–80 m: renders a straight
//! road of the default town with and without one object in the ego's lane and counts the pixels
//! that change, for several cameras. The table behind the hazard preset's camera
//! (docs/EVALUATION.md, "What the camera can see").
//!
//! `cargo run --release -p sim-core --example hazard_pixels`

use sim_core::camera::{Camera, CameraConfig, Image, SceneBox, car_box, prop_box, walker_box};
use sim_core::collision::Obb;
use sim_core::hazards::prop::{Prop, PropKind};
use sim_core::hazards::walker::{WALKER_HALF, WALKER_HEIGHT};
use sim_core::math::Vec2;
use sim_core::scenario::{EvalRoute, eval_route};
use sim_core::town::Town;

/// The objects the hazard kinds show: a car (stalled, cutting in, braking, overtaking, running
/// the junction), a walker, a cone and the closure's barrier.
const OBJECTS: [&str; 4] = ["car", "walker", "cone", "barrier"];

fn object(name: &str, at: Vec2, heading: f32) -> SceneBox {
    match name {
        "car" => car_box(Obb::new(at, Vec2::new(2.25, 0.95), heading), 0),
        "walker" => walker_box(Obb::new(at, Vec2::splat(WALKER_HALF), heading), WALKER_HEIGHT),
        "cone" => prop_box(&Prop { body: Obb::new(at, Vec2::splat(0.2), heading), height: 0.75, kind: PropKind::Cone }, 0),
        _ => prop_box(&Prop { body: Obb::new(at, Vec2::new(0.25, 1.4), heading), height: 1.0, kind: PropKind::Barrier }, 0),
    }
}

fn main() {
    let town = Town::default_town();
    let route = eval_route(&town, EvalRoute::StraightHighway, 8.0).expect("the default town has its straight highway");
    let (start, heading) = (route.path.start(), route.path.heading_at(0.0));
    let cameras = [
        ("48x48, 90°", CameraConfig { width: 48, height: 48, ..CameraConfig::default() }),
        ("84x84, 90°", CameraConfig::default()),
        ("48x48, 60°", CameraConfig { width: 48, height: 48, hfov_deg: 60.0, ..CameraConfig::default() }),
        ("64x64, 60°", CameraConfig { width: 64, height: 64, hfov_deg: 60.0, ..CameraConfig::default() }),
        ("64x64, 60°, pitch 4°", CameraConfig { width: 64, height: 64, hfov_deg: 60.0, pitch_deg: 4.0, ..CameraConfig::default() }),
        ("84x84, 60°", CameraConfig { hfov_deg: 60.0, ..CameraConfig::default() }),
    ];
    let distances = [20.0f32, 30.0, 40.0, 50.0, 60.0, 70.0, 80.0];
    println!("Pixels that change when the object stands in the ego's lane, d metres ahead (straight_highway, default_town):\n");
    print!("| camera | object |");
    for d in distances {
        print!(" {d:.0} m |");
    }
    println!();
    println!("|---|---|{}", "---:|".repeat(distances.len()));
    for (name, cfg) in &cameras {
        let mut camera = Camera::new(cfg).expect("a valid camera");
        let mut empty = Image::new(0, 0, 1);
        camera.render(&town, start, heading, &[], &mut empty);
        for obj in OBJECTS {
            print!("| {name} | {obj} |");
            for d in distances {
                let at = route.path.point_at(d);
                let mut with = Image::new(0, 0, 1);
                camera.render(&town, start, heading, &[object(obj, at, route.path.heading_at(d))], &mut with);
                let changed = with.data.iter().zip(&empty.data).filter(|(a, b)| a != b).count();
                print!(" {changed} |");
            }
            println!();
        }
    }
}
