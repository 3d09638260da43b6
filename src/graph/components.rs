//! Connected components of the graph and how each one's gauge freedom is removed.
//!
//! A pose graph made only of relative factors is invariant to moving all of its poses
//! together. Each connected component therefore needs an anchor: a fixed variable or a
//! unary (prior) factor. Components without one get their first variable fixed
//! automatically and are reported as such.

use super::factors::Factor;
use super::VarKey;
use serde::{Deserialize, Serialize};

/// What removes the gauge freedom of one connected component.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(tag = "type", content = "var", rename_all = "snake_case")]
pub enum Anchor {
    /// The user fixed this variable.
    Fixed(VarKey),
    /// At least one prior factor on a variable of the component.
    Prior,
    /// Nothing did; the solver held this variable (the component's first) at its estimate.
    AutoFixed(VarKey),
}

/// One connected component of the graph.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ComponentInfo {
    /// Number of variables in the component.
    pub variables: usize,
    /// Number of factors in the component.
    pub factors: usize,
    /// First variable of the component (insertion order).
    pub first: VarKey,
    /// How the gauge is fixed.
    pub anchor: Anchor,
}

/// Union–find with path halving.
struct DisjointSets {
    parent: Vec<usize>,
}

impl DisjointSets {
    fn new(n: usize) -> Self {
        Self {
            parent: (0..n).collect(),
        }
    }

    fn find(&mut self, mut x: usize) -> usize {
        while self.parent[x] != x {
            self.parent[x] = self.parent[self.parent[x]];
            x = self.parent[x];
        }
        x
    }

    fn union(&mut self, a: usize, b: usize) {
        let (ra, rb) = (self.find(a), self.find(b));
        if ra != rb {
            // Keep the smaller index as root so a component's root is its first variable.
            let (lo, hi) = if ra < rb { (ra, rb) } else { (rb, ra) };
            self.parent[hi] = lo;
        }
    }
}

/// Finds the connected components and the variables that must be held to fix the gauge.
///
/// Returns the components (ordered by their first variable) and the effective "held" flag
/// of every variable (user-fixed or auto-fixed).
pub(crate) fn analyse(
    keys: &[VarKey],
    fixed: &[bool],
    factors: &[Factor],
) -> (Vec<ComponentInfo>, Vec<bool>) {
    let n = keys.len();
    let mut sets = DisjointSets::new(n);
    for f in factors {
        if !f.is_unary() {
            let [a, b] = f.vars();
            sets.union(a, b);
        }
    }
    let mut root_slot = vec![usize::MAX; n];
    // (info, first variable index, first user-fixed variable, has a prior)
    let mut comps: Vec<(ComponentInfo, usize, Option<usize>, bool)> = Vec::new();
    for v in 0..n {
        let r = sets.find(v);
        if root_slot[r] == usize::MAX {
            root_slot[r] = comps.len();
            comps.push((
                ComponentInfo {
                    variables: 0,
                    factors: 0,
                    first: keys[v],
                    anchor: Anchor::AutoFixed(keys[v]),
                },
                v,
                None,
                false,
            ));
        }
        let c = &mut comps[root_slot[r]];
        c.0.variables += 1;
        if fixed[v] && c.2.is_none() {
            c.2 = Some(v);
        }
    }
    for f in factors {
        let r = sets.find(f.vars()[0]);
        let c = &mut comps[root_slot[r]];
        c.0.factors += 1;
        if f.is_unary() {
            c.3 = true;
        }
    }
    let mut held = fixed.to_vec();
    let mut out = Vec::with_capacity(comps.len());
    for (mut info, first, fixed_var, has_prior) in comps {
        info.anchor = match (fixed_var, has_prior) {
            (Some(v), _) => Anchor::Fixed(keys[v]),
            (None, true) => Anchor::Prior,
            (None, false) => {
                held[first] = true;
                Anchor::AutoFixed(info.first)
            }
        };
        out.push(info);
    }
    (out, held)
}
