//! The opening of the demo's report: the pipeline told as the story a workshop lives through
//! (images -> camera -> poses -> calibrated robot -> what the model leaves out -> corrected
//! program), each step with what went in and came out, the check of the stage that did it, and
//! one figure; the summary of every check follows it.

use crate::report::{Block, Section};

/// One step of the story: its heading, what goes in and comes out, and the ids of the demo's
/// sections that show it (the first with a figure lends it).
struct Step {
    title: &'static str,
    in_out: &'static str,
    ids: &'static [&'static str],
}

const STEPS: [Step; 5] = [
    Step {
        title: "Images to a calibrated camera",
        in_out: "photographs of a printed board -> the camera's focal lengths, centre and lens, each with its standard deviation, checked on held-out views",
        ids: &["camera-real", "camera-own-corners"],
    },
    Step {
        title: "Images and robot poses to hand-eye and metric poses",
        in_out: "images taken at recorded robot poses -> where the camera sits on the robot (or in the cell) and one 6-D target pose per image with its covariance",
        ids: &["handeye-real", "measure-real", "positioner-real"],
    },
    Step {
        title: "Poses to a calibrated robot",
        in_out: "measured poses (cameras in place of a laser tracker, or the tracker) -> the robot's kinematic parameters with their uncertainties, scored on poses left out of the fit",
        ids: &["cameras", "ur5-calibration", "cell-calibration"],
    },
    Step {
        title: "What the model leaves out",
        in_out: "the residuals of the calibration -> the physics the geometric model misses (compliance, backlash, scale, ...), claimed only on held-out improvement",
        ids: &["ur5-diagnose-summary", "ur5-finding-1", "force-diagnose"],
    },
    Step {
        title: "A calibrated robot to a corrected program",
        in_out: "the calibration with the diagnosed physics in it -> the program's joint commands corrected so the robot reaches what the nominal model meant",
        ids: &["ur5-compensation", "corrected-commands"],
    },
];

/// The story section built from the demo's `sections` (already run): per step, the stages'
/// checks in words and the first figure among them; a stage that did not run is named.
pub fn story_section(sections: &[Section]) -> Section {
    let mut s = Section::new("story", "The pipeline, step by step");
    s.text(
        "What a workshop does with ferrocal after reconfiguring a robot, on the shared real recordings and the built-in simulated cell. Each step names what goes in and what comes out, the check its stage passed or failed, and one figure; the stage's own section (folded below the summary) has the rest.",
    );
    let mut rows = Vec::new();
    for (k, step) in STEPS.iter().enumerate() {
        let found: Vec<&Section> = step.ids.iter().filter_map(|id| sections.iter().find(|x| x.id == *id)).collect();
        let mut lines = vec![format!("{}. {}: {}.", k + 1, step.title, step.in_out)];
        for x in &found {
            match &x.status {
                Some(c) => lines.push(format!("{} [{}]: {}", x.title, c.status.name(), brief(&c.detail))),
                None => lines.push(format!("{}: shown without a check.", x.title)),
            }
            rows.push(vec![
                format!("{}", k + 1),
                x.title.clone(),
                x.status.as_ref().map(|c| c.status.name().to_string()).unwrap_or_else(|| "-".into()),
            ]);
        }
        if found.is_empty() {
            lines.push("No stage of this step ran in this demo.".into());
        }
        s.text(lines.join(" "));
        let figure = found.iter().flat_map(|x| x.blocks.iter()).find(|b| matches!(b, Block::Figure { .. }));
        if let Some(Block::Figure { caption, svg }) = figure {
            s.figure(&format!("Step {}: {caption}", k + 1), svg.clone());
        }
    }
    s.table("The stages of each step", &["step", "stage (section below)", "status"], rows);
    s
}

/// A check's detail cut after about [`BRIEF_CHARS`] characters at a word (the section below
/// has all of it).
fn brief(detail: &str) -> String {
    if detail.chars().count() <= BRIEF_CHARS {
        return detail.to_string();
    }
    let cut: String = detail.chars().take(BRIEF_CHARS).collect();
    let cut = cut.rsplit_once(' ').map_or(cut.as_str(), |(a, _)| a);
    format!("{cut} ... (the section below has the rest)")
}

/// How much of a check's detail the story shows.
const BRIEF_CHARS: usize = 240;

#[cfg(test)]
mod tests {
    use super::*;
    use ferrocal_calib::check::Check;

    #[test]
    fn every_step_names_its_stages_their_checks_and_lends_a_figure() {
        let mut cam = Section::new("camera-real", "Real camera");
        cam.check(Check::from_bool("real camera", true, "RMS 0.19 px <= 0.5 px"));
        cam.figure("residuals", "<svg>cam</svg>".into());
        let mut diag = Section::new("ur5-diagnose-summary", "Diagnose");
        diag.check(Check::from_bool("diagnose", false, "nothing claimed"));
        let story = story_section(&[cam, diag, Section::new("unrelated", "Other")]);
        let texts: Vec<&str> =
            story.blocks.iter().filter_map(|b| if let Block::Text(t) = b { Some(t.as_str()) } else { None }).collect();
        assert_eq!(texts.len(), 1 + STEPS.len());
        assert!(texts[1].starts_with("1. Images to a calibrated camera") && texts[1].contains("RMS 0.19 px <= 0.5 px"));
        assert!(texts[2].contains("No stage of this step ran"));
        assert!(texts[4].contains("Diagnose [") && texts[4].contains("nothing claimed"));
        let figures = story.blocks.iter().filter(|b| matches!(b, Block::Figure { .. })).count();
        assert_eq!(figures, 1);
    }

    #[test]
    fn a_long_detail_is_cut_at_a_word() {
        let long = "word ".repeat(100);
        let b = brief(&long);
        assert!(b.len() < BRIEF_CHARS + 60 && b.ends_with("word ... (the section below has the rest)"), "{b}");
        assert_eq!(brief("short"), "short");
    }
}
