//! Tests of the report builder.
use super::*;

fn report() -> Report {
    let mut r = Report::new("t", Provenance::new(Value::Null));
    let mut a = Section::new("a", "A");
    a.status(true, "within 1 mm");
    let mut b = Section::new("b", "B");
    b.skipped("x.csv is not present");
    let mut c = Section::new("c", "C");
    c.reported("numbers only");
    r.sections = vec![a, b, c];
    r
}

#[test]
fn skipped_and_reported_sections_are_not_ok_and_say_so() {
    let r = report();
    let j = r.to_json();
    let s = &j["sections"];
    assert_eq!(s["a"]["ok"], Value::Bool(true));
    assert_eq!(s["a"]["status"], "within 1 mm");
    assert_eq!(s["a"]["check"], "pass");
    for (k, want) in [("b", "skipped: x.csv is not present"), ("c", "reported: numbers only")] {
        assert!(s[k].get("ok").is_none(), "{k}: {}", s[k]);
        assert_eq!(s[k]["status"], want);
    }
    let html = r.to_html();
    assert!(html.contains("<span class=\"note\">skipped: x.csv is not present</span>"), "{html}");
    assert!(html.contains("x.csv is not present: section skipped."));
    assert!(!r.failed());
}

#[test]
fn the_verdict_box_opens_the_report_and_its_slot_is_filled_later() {
    use ferrocal_calib::verdict::Check as VCheck;
    let v = Verdict::new(
        vec![
            VCheck::at_most("camera.rms_px", "reprojection RMS", "px", 0.7, 0.5, 1.0),
            VCheck::at_least("camera.views", "views", "", 12.0, 10.0, 5.0),
        ],
        "retake the blurred views <3>",
    );
    let mut r = report();
    let without = r.to_html();
    assert!(without.contains(VERDICT_SLOT), "a report without its verdict keeps the slot");
    r.verdict = Some(v.clone());
    let html = r.to_html();
    let (box_at, nav_at) = (html.find("class=\"verdict v-warning\"").unwrap(), html.find("<nav>").unwrap());
    assert!(box_at < nav_at, "the box comes before everything else");
    assert!(html.contains("Verdict: WARNING"));
    assert!(html.contains("retake the blurred views &lt;3&gt;"), "escaped");
    assert!(html.contains("reprojection RMS 0.7 px &gt; 0.5 px (warning)"));
    assert!(!html.contains(VERDICT_SLOT));
    assert_eq!(r.to_json()["verdict"]["status"], "warning");
    assert_eq!(without.replacen(VERDICT_SLOT, &verdict_box(&v), 1), html, "filling the slot gives the same page");
}

#[test]
fn sections_after_the_first_fold_their_details_unless_they_failed() {
    let mut r = Report::new("t", Provenance::new(Value::Null));
    for (id, ok) in [("a", true), ("b", true), ("c", true), ("d", false)] {
        let mut s = Section::new(id, id);
        s.text(format!("lead of {id}")).table("numbers", &["x"], vec![vec!["1".into()]]).status(ok, "x");
        r.sections.push(s);
    }
    let html = r.to_html();
    let body = |id: &str| {
        let from = html.find(&format!("<section id=\"{id}\"")).unwrap();
        let to = from + html[from..].find("</section>").unwrap();
        html[from..to].to_string()
    };
    assert!(!body("a").contains("<details>") && !body("b").contains("<details>"), "the first two are whole");
    let c = body("c");
    let (lead, fold) = (c.find("lead of c").unwrap(), c.find("<details>").unwrap());
    assert!(lead < fold && c.find("<table>").unwrap() > fold, "{c}");
    assert!(c.contains("1 more item (tables"), "{c}");
    assert!(!body("d").contains("<details>"), "a failed section is shown whole");
    r.open_sections = usize::MAX;
    assert!(!r.to_html().contains("<details>"));
    // A long report folds its later sections whole, headings as the table of contents.
    r.open_sections = 2;
    for k in 0..COMPACT_AFTER {
        let mut s = Section::new(&format!("x{k}"), "X");
        s.text("lead").table("t", &["x"], vec![]);
        r.sections.push(s);
    }
    let html = r.to_html();
    assert!(!html.contains("<nav>"));
    let x0 = &html[html.find("<section id=\"x0\"").unwrap()..];
    assert!(x0.starts_with("<section id=\"x0\" class=\"folded\"><details><summary><strong>X</strong>"), "{x0}");
    assert!(x0.find("lead").unwrap() > x0.find("</summary>").unwrap(), "the lead is folded too");
    let d = &html[html.find("<section id=\"d\"").unwrap()..];
    assert!(!d[..d.find("</section>").unwrap()].contains("<details>"), "a failed section is still whole");
}

#[test]
fn the_summary_counts_and_lists_every_check() {
    let mut r = report();
    let mut d = Section::new("d", "D");
    d.status(false, "3 mm, limit 1 mm");
    r.sections.push(d);
    assert!(r.failed());
    let s = r.summary_section();
    assert!(s.status.is_none(), "the summary does not count itself");
    assert_eq!(s.data["counts"]["passed"], 1);
    assert_eq!(s.data["counts"]["failed"], 1);
    assert_eq!(s.data["counts"]["skipped"], 1);
    assert_eq!(s.data["counts"]["reported"], 1);
    let statuses: Vec<&str> =
        s.data["sections"].as_array().unwrap().iter().map(|x| x["status"].as_str().unwrap()).collect();
    assert_eq!(statuses, ["pass", "skipped", "reported", "fail"]);
}
