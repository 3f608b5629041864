use super::Trees;

/// Three trees over inputs a, b, c, written by hand to LightGBM's text layout:
/// - tree 0: a <= 1 (missing: none, so NaN reads as 0) → b <= 0.5 (missing: NaN, which goes
///   left) → 20 | 30; else 10;
/// - tree 1: c <= 0 → 1 | 2, where a zero (|c| ≤ 1e-35, NaN included) is missing and goes
///   right;
/// - tree 2: one leaf, 0.5.
fn model(objective: &str, tree1_extra: &str) -> String {
    format!(
        "tree\nversion=v4\nnum_class=1\nnum_tree_per_iteration=1\nlabel_index=0\nmax_feature_idx=2\n\
objective={objective}\nfeature_names=a b c\nfeature_infos=[0:3] [0:1] [-1:1]\ntree_sizes=1 1 1\n\n\
Tree=0\nnum_leaves=3\nnum_cat=0\nsplit_feature=0 1\nsplit_gain=1 1\nthreshold=1 0.5\n\
decision_type=2 10\nleft_child=1 -2\nright_child=-1 -3\nleaf_value=10 20 30\n\
leaf_weight=1 1 1\nleaf_count=1 1 1\ninternal_value=0 0\ninternal_weight=0 0\n\
internal_count=3 2\nis_linear=0\nshrinkage=1\n\n\n\
Tree=1\nnum_leaves=2\nnum_cat=0\nsplit_feature=2\nsplit_gain=1\nthreshold=0\n\
decision_type=4\nleft_child=-1\nright_child=-2\nleaf_value=1 2\n{tree1_extra}shrinkage=0.05\n\n\n\
Tree=2\nnum_leaves=1\nnum_cat=0\nshrinkage=1\nleaf_value=0.5\n\n\n\
end of trees\n\nfeature_importances:\na=1\n\nparameters:\n[objective: {objective}]\nend of parameters\n"
    )
}

#[test]
fn follows_lightgbms_decisions_and_missing_values() {
    let t = Trees::parse(&model("regression", "")).unwrap();
    assert_eq!(t.len(), 3);
    assert_eq!(t.feature_names(), ["a", "b", "c"]);
    let nan = f64::NAN;
    for (x, want) in [
        ([2.0, 0.0, 5.0], 10.0 + 2.0 + 0.5),
        // On the threshold: left (x <= threshold).
        ([1.0, 0.5, -1.0], 20.0 + 1.0 + 0.5),
        ([1.0, 0.5000001, -1.0], 30.0 + 1.0 + 0.5),
        // a missing with missing type none: read as 0, so left; b NaN goes left by default;
        // c = 0 is missing (zero) and goes right.
        ([nan, nan, 0.0], 20.0 + 2.0 + 0.5),
        // Below 1e-35 is zero; -1e-30 is not, so c <= 0 goes left.
        ([0.0, 1.0, 1e-40], 30.0 + 2.0 + 0.5),
        ([0.0, 1.0, -1e-30], 30.0 + 1.0 + 0.5),
        // NaN where NaN is not the missing value reads as 0, which is missing (zero): right.
        ([0.0, 1.0, nan], 30.0 + 2.0 + 0.5),
        ([f64::INFINITY, 0.0, f64::NEG_INFINITY], 10.0 + 1.0 + 0.5),
    ] {
        assert_eq!(t.predict(&x), want, "{x:?}");
    }
}

#[test]
fn refuses_what_it_cannot_evaluate_and_says_where() {
    let err = |text: String| format!("{:#}", Trees::parse(&text).unwrap_err());
    assert!(err(model("poisson", "")).contains("objective 'poisson'"));
    assert!(err(model("regression", "").replacen(
        "objective=regression\n",
        "objective=regression\naverage_output\n",
        1
    ))
    .contains("random forest"));
    let e =
        err(model("regression", "")
            .replace("num_cat=0\nsplit_feature=2", "num_cat=1\nsplit_feature=2"));
    assert!(e.contains("Tree=1") && e.contains("categorical"), "{e}");
    let e = err(model("regression", "").replace("decision_type=4", "decision_type=5"));
    assert!(e.contains("Tree=1") && e.contains("categorical"), "{e}");
    let e = err(model("regression", "").replace("split_feature=2\n", "split_feature=3\n"));
    assert!(e.contains("split_feature[0] = 3"), "{e}");
    let e = err(model("regression", "").replace("left_child=1 -2", "left_child=0 -2"));
    assert!(e.contains("Tree=0") && e.contains("child 0"), "{e}");
    let e = err(model("regression", "").replace("right_child=-1 -3", "right_child=-1 -4"));
    assert!(e.contains("child -4"), "{e}");
    let e = err(model("regression", "").replace("leaf_value=10 20 30", "leaf_value=10 20"));
    assert!(e.contains("leaf_value has 2 entries, expected 3"), "{e}");
    let e = err(model("regression", "").replace("threshold=1 0.5", "threshold=1 x"));
    assert!(e.contains("threshold: 'x' is not a number"), "{e}");
    let e = err(model("regression", "is_linear=1\n"));
    assert!(e.contains("linear"), "{e}");
    assert!(err("not a model".into()).contains("no Tree="));
    // Truncated anywhere: an error or a model, never a panic.
    let text = model("regression", "");
    for cut in 0..text.len() {
        if text.is_char_boundary(cut) {
            let _ = Trees::parse(&text[..cut]);
        }
    }
}

#[test]
fn without_missing_values_a_nan_reads_as_zero_at_every_split() {
    // Every missing type "none" (LightGBM's default): the row's NaNs read as 0 once.
    let text = model("regression", "")
        .replace("decision_type=2 10", "decision_type=2 0")
        .replace("decision_type=4", "decision_type=2");
    let t = Trees::parse(&text).unwrap();
    let nan = f64::NAN;
    for (x, want) in [
        // a → 0 ≤ 1, b → 0 ≤ 0.5, c → 0 ≤ 0.
        ([nan, nan, nan], 20.0 + 1.0 + 0.5),
        ([nan, 1.0, 1e-40], 30.0 + 2.0 + 0.5),
        ([2.0, nan, -0.0], 10.0 + 1.0 + 0.5),
    ] {
        assert_eq!(t.predict(&x), want, "{x:?}");
    }
}
