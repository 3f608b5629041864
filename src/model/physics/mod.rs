//! The five physics power models of the paper (D'Andrea with and without headwind,
//! Dorling, Stolaroff, Kirschstein, Tseng). Owner: physics (issue 4).
