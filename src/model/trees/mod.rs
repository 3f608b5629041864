//! Gradient-boosted regression trees from LightGBM's text model (`Booster.save_model`), on
//! the CPU path: what the LSTM's card blends in (`trees`, [`super::lstm`]). Parsing takes
//! the text, never a file; evaluation follows LightGBM's `Tree::NumericalDecision`:
//!
//! - `decision_type` bit 0: categorical (refused here), bit 1: a missing value goes left,
//!   bits 2–3: what counts as missing (0 none: NaN is read as 0; 1 zero: |x| ≤ 1e-35;
//!   2 NaN);
//! - otherwise `x <= threshold` goes left; a child below 0 is the leaf `!child`;
//! - the estimate is the sum of every tree's leaf (shrinkage is already in the leaf values,
//!   and `boost_from_average` in the first tree's).
//!
//! Only objectives whose output is the raw score are read (regression, L1, Huber, Fair,
//! quantile, MAPE); linear trees and random-forest averaging are refused.

use anyhow::{bail, Context};

/// One node: a split, with children (below 0: the leaf `!child`).
#[derive(Debug, Clone, Copy)]
struct Node {
    threshold: f64,
    feature: u32,
    left: i32,
    right: i32,
    /// Bit 1: missing goes left; bits 2–3: missing type.
    decision: u8,
}

#[derive(Debug, Clone)]
struct Tree {
    nodes: Vec<Node>,
    leaves: Vec<f64>,
}

/// A LightGBM regression model.
#[derive(Debug, Clone)]
pub struct Trees {
    trees: Vec<Tree>,
    names: Vec<String>,
    /// No split treats a value as missing (every missing type is "none", LightGBM's default
    /// without NaN or zero-as-missing in the training data): a NaN input reads as 0 and
    /// every split is a plain `x <= threshold`.
    plain: bool,
}

const DEFAULT_LEFT: u8 = 2;
const ZERO_THRESHOLD: f64 = 1e-35;
const IDENTITY_OBJECTIVES: [&str; 7] = [
    "regression",
    "regression_l1",
    "huber",
    "fair",
    "quantile",
    "mape",
    "regression_l2",
];

impl Node {
    /// What counts as missing: 0 none, 1 zero, 2 NaN.
    fn missing_type(&self) -> u8 {
        (self.decision >> 2) & 3
    }

    /// The child `x` goes to (LightGBM's `NumericalDecision`).
    #[inline(always)]
    fn next(&self, x: &[f64]) -> i32 {
        let mut v = x[self.feature as usize];
        let missing = self.missing_type();
        if v.is_nan() && missing != 2 {
            v = 0.0;
        }
        let is_missing =
            (missing == 1 && v.abs() <= ZERO_THRESHOLD) || (missing == 2 && v.is_nan());
        let left = if is_missing {
            self.decision & DEFAULT_LEFT != 0
        } else {
            v <= self.threshold
        };
        if left {
            self.left
        } else {
            self.right
        }
    }

    /// [`Self::next`] where no value is missing (the row's NaNs already read as 0).
    #[inline(always)]
    fn next_plain(&self, x: &[f64]) -> i32 {
        if x[self.feature as usize] <= self.threshold {
            self.left
        } else {
            self.right
        }
    }
}

/// Trees walked side by side: each walk is a chain of dependent loads, so several at once
/// keep the memory system busy (about twice as fast as one at a time here).
const LANES: usize = 8;

impl Trees {
    /// Read LightGBM's text model. The error names the tree and the key.
    pub fn parse(text: &str) -> anyhow::Result<Trees> {
        let mut lines = text.lines();
        let mut header = std::collections::HashMap::new();
        let mut found = false;
        for line in lines.by_ref() {
            if line.starts_with("Tree=") {
                found = true;
                break;
            }
            // `average_output` (a random forest) is a bare key.
            let (k, v) = line.split_once('=').unwrap_or((line, ""));
            header.insert(k.trim(), v.trim());
        }
        if !found {
            bail!("no Tree= block: not a LightGBM text model");
        }
        let objective = header.get("objective").copied().unwrap_or("");
        let name = objective.split_whitespace().next().unwrap_or("");
        if !IDENTITY_OBJECTIVES.contains(&name) {
            bail!("objective '{objective}': only regression objectives whose output is the raw score are read");
        }
        if header.contains_key("average_output") {
            bail!("a random forest (average_output): only boosted trees are read");
        }
        if let Some(k) = header.get("num_class").filter(|v| **v != "1") {
            bail!("num_class = {k}: one output is read");
        }
        let names: Vec<String> = header
            .get("feature_names")
            .context("no feature_names line")?
            .split_whitespace()
            .map(String::from)
            .collect();
        // One block per `Tree=` line, up to `end of trees`.
        let mut blocks: Vec<Vec<&str>> = vec![Vec::new()];
        for line in lines {
            if line.starts_with("Tree=") {
                blocks.push(Vec::new());
            } else if line.starts_with("end of trees") {
                break;
            } else if !line.trim().is_empty() {
                if let Some(b) = blocks.last_mut() {
                    b.push(line);
                }
            }
        }
        let trees = blocks
            .iter()
            .enumerate()
            .map(|(i, b)| parse_tree(b, names.len()).with_context(|| format!("Tree={i}")))
            .collect::<anyhow::Result<Vec<Tree>>>()?;
        if trees.is_empty() {
            bail!("no tree");
        }
        let plain = trees
            .iter()
            .all(|t| t.nodes.iter().all(|n| n.missing_type() == 0));
        Ok(Trees {
            trees,
            names,
            plain,
        })
    }

    /// Input names, in the order [`Self::predict`] reads them.
    pub fn feature_names(&self) -> &[String] {
        &self.names
    }

    /// How many trees.
    pub fn len(&self) -> usize {
        self.trees.len()
    }

    /// Never true for a parsed model.
    pub fn is_empty(&self) -> bool {
        self.trees.is_empty()
    }

    /// The estimate for one row of inputs (`feature_names()`' order; NaN where missing).
    pub fn predict(&self, x: &[f64]) -> f64 {
        debug_assert_eq!(x.len(), self.names.len());
        if self.plain {
            // NaN reads as 0 under missing type "none": once for the row, not at every split.
            let mut row = [0.0; 256];
            if let Some(r) = row.get_mut(..x.len()) {
                for (r, v) in r.iter_mut().zip(x) {
                    *r = if v.is_nan() { 0.0 } else { *v };
                }
                return self.walk(&row[..x.len()], Node::next_plain);
            }
        }
        self.walk(x, Node::next)
    }

    /// Every tree's leaf for `x`, summed in tree order; `next` takes one split.
    #[inline(always)]
    fn walk(&self, x: &[f64], next: impl Fn(&Node, &[f64]) -> i32) -> f64 {
        let mut sum = 0.0;
        for chunk in self.trees.chunks(LANES) {
            // A node index, or below 0 the leaf `!i`; a one-leaf tree starts at its leaf.
            let mut at = [-1i32; LANES];
            for (a, t) in at.iter_mut().zip(chunk) {
                *a = if t.nodes.is_empty() { -1 } else { 0 };
            }
            loop {
                let mut walking = false;
                for (a, t) in at.iter_mut().zip(chunk) {
                    if *a >= 0 {
                        *a = next(&t.nodes[*a as usize], x);
                        walking = true;
                    }
                }
                if !walking {
                    break;
                }
            }
            // In tree order, as LightGBM adds them, so the sum is its to the bit.
            for (a, t) in at.iter().zip(chunk) {
                sum += t.leaves[!*a as usize];
            }
        }
        sum
    }
}

fn field<'a>(block: &[&'a str], key: &str) -> Option<&'a str> {
    block
        .iter()
        .find_map(|l| l.split_once('=').filter(|(k, _)| *k == key).map(|(_, v)| v))
}

fn numbers<T: std::str::FromStr>(block: &[&str], key: &str, n: usize) -> anyhow::Result<Vec<T>> {
    let v = field(block, key).with_context(|| format!("no {key}"))?;
    let out = v
        .split_whitespace()
        .map(|s| {
            s.parse::<T>()
                .map_err(|_| anyhow::anyhow!("{key}: '{s}' is not a number"))
        })
        .collect::<anyhow::Result<Vec<T>>>()?;
    if out.len() != n {
        bail!("{key} has {} entries, expected {n}", out.len());
    }
    Ok(out)
}

fn parse_tree(block: &[&str], n_features: usize) -> anyhow::Result<Tree> {
    let leaves_n: usize = field(block, "num_leaves")
        .context("no num_leaves")?
        .trim()
        .parse()
        .context("num_leaves")?;
    if leaves_n == 0 {
        bail!("num_leaves = 0");
    }
    if field(block, "num_cat").is_some_and(|v| v.trim() != "0") {
        bail!("categorical splits are not read");
    }
    if field(block, "is_linear").is_some_and(|v| v.trim() != "0") {
        bail!("linear trees are not read");
    }
    let leaves: Vec<f64> = numbers(block, "leaf_value", leaves_n)?;
    if leaves.iter().any(|v| !v.is_finite()) {
        bail!("leaf_value holds a value that is not finite");
    }
    if leaves_n == 1 {
        return Ok(Tree {
            nodes: Vec::new(),
            leaves,
        });
    }
    let s = leaves_n - 1;
    let feature: Vec<u32> = numbers(block, "split_feature", s)?;
    let threshold: Vec<f64> = numbers(block, "threshold", s)?;
    let decision: Vec<u8> = numbers(block, "decision_type", s)?;
    let left: Vec<i32> = numbers(block, "left_child", s)?;
    let right: Vec<i32> = numbers(block, "right_child", s)?;
    let child_ok = |c: i32| {
        if c >= 0 {
            (c as usize) < s
        } else {
            ((!c) as usize) < leaves_n
        }
    };
    let mut nodes = Vec::with_capacity(s);
    for i in 0..s {
        if feature[i] as usize >= n_features {
            bail!(
                "split_feature[{i}] = {} but the model has {n_features} inputs",
                feature[i]
            );
        }
        if decision[i] & 1 != 0 {
            bail!("decision_type[{i}]: categorical splits are not read");
        }
        // Children come after their parent in LightGBM's layout, so a walk always ends.
        for c in [left[i], right[i]] {
            if !child_ok(c) || (c >= 0 && c as usize <= i) {
                bail!("node {i}: child {c} is out of place");
            }
        }
        if threshold[i].is_nan() {
            bail!("threshold[{i}] is NaN");
        }
        nodes.push(Node {
            threshold: threshold[i],
            feature: feature[i],
            left: left[i],
            right: right[i],
            decision: decision[i],
        });
    }
    Ok(Tree { nodes, leaves })
}

#[cfg(test)]
mod tests;
