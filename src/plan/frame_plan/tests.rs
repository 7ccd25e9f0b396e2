//! Stage 2, the per-frame plan as a value: its unit tests (a SAT mode needs its tables; plans are values
//! with hashes and chained uploads).

use super::*;
use crate::plan::clipmap::ClipmapOptions;
use crate::source::procedural::{generate, ProceduralParams};

#[test]
fn a_sat_mode_without_tables_is_a_construction_error() {
    assert!(matches!(
        LodSetup::new(LodMode::Sat, None),
        Err(Error::Invalid { .. })
    ));
    assert!(matches!(
        LodSetup::new(LodMode::Distance, None),
        Ok(LodSetup::Distance)
    ));
}

#[test]
fn plans_are_values_with_hashes_and_chained_uploads() {
    let hm = generate(&ProceduralParams {
        size: 129,
        ..ProceduralParams::default()
    })
    .expect("terrain");
    let profile = Profile::load("gles3-low").expect("profile");
    let mut cm = Clipmap::new(&hm, &profile, ClipmapOptions::default()).expect("clipmap");
    let cam = Camera::default_for(&hm).expect("camera");
    let mut planner = Planner::new(&profile, &cm, LodSetup::Distance).expect("planner");
    let mut plan = planner.new_plan();
    cm.update(cam.eye).expect("update");
    planner
        .plan(&cm, &cam, &PlanParams::default(), &mut plan)
        .expect("plan");
    assert_eq!((plan.frame_index(), plan.since()), (Some(0), None));
    assert!(!plan.draws().is_empty() && plan.planned().len() == plan.draws().len());
    let first = plan.hash();
    let samples = plan.stats().upload_samples;
    assert!(samples > 0 && samples <= u64::from(profile.budget.update_samples_per_frame));
    // The same frame again: nothing to upload, the same draws.
    planner
        .plan(&cm, &cam, &PlanParams::default(), &mut plan)
        .expect("plan");
    assert!(plan.uploads().is_empty());
    assert_ne!(plan.hash(), first);
    // A fresh planner over the same frame gives the first plan again.
    let mut again = Planner::new(&profile, &cm, LodSetup::Distance).expect("planner");
    let mut p2 = again.new_plan();
    again
        .plan(&cm, &cam, &PlanParams::default(), &mut p2)
        .expect("plan");
    assert_eq!(p2.hash(), first);
}
