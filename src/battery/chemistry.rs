//! Cell chemistries, their voltage windows and default OCV shapes, and robust cell-count
//! detection from a resting voltage.

use serde::{Deserialize, Serialize};

use super::ocv::OcvCurve;

/// Cell chemistry. Windows are *resting* (open-circuit) voltages per cell.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "lowercase")]
#[derive(strum::IntoStaticStr, strum::EnumString)]
#[strum(serialize_all = "lowercase")]
pub enum Chemistry {
    /// LiPo / LiCoO2-class, 4.20 V full.
    LiPo,
    /// High-voltage LiPo (e.g. DJI TB48D), 4.35 V full.
    LiHv,
    /// Li-ion when the cathode is not named (MAV_BATTERY_TYPE_LION, `li-ion`): the measured
    /// LiCoO2 18650's curve, 4.20 V full, usable down to ~3.0 V.
    LiIon,
    /// Li-ion with a nickel cathode (NMC or NCA 18650/21700, most drone Li-ion packs), named
    /// by the config or the flag (`nmc`, `nca`): the same window, the NMC811 cell's curve.
    #[strum(serialize = "nmc")]
    #[serde(rename = "nmc")]
    LiIonNmc,
    /// Lithium iron phosphate, 3.65 V full, a flat plateau near 3.3 V.
    #[strum(serialize = "lifepo4")]
    #[serde(rename = "lifepo4")]
    LiFePo4,
}

/// LiPo default SoC table: the widely circulated hobby LiPo resting-voltage table
/// (4.20 = 100 %, 3.84 = 50 %, 3.69 = 10 %, 3.27 = 0 %). Pairs are (V/cell, SoC).
const LIPO: [(f64, f64); 14] = [
    (3.27, 0.0),
    (3.61, 0.05),
    (3.69, 0.10),
    (3.73, 0.20),
    (3.77, 0.30),
    (3.80, 0.40),
    (3.84, 0.50),
    (3.87, 0.60),
    (3.91, 0.65),
    (3.95, 0.70),
    (4.02, 0.80),
    (4.08, 0.85),
    (4.11, 0.90),
    (4.20, 1.00),
];

/// Li-ion default: the open-circuit voltage of a measured 18650, the Sony US-18650 (LiCoO2 /
/// graphite) of Ramadass et al., "Development of First Principles Capacity Fade Model for
/// Li-Ion Cells", J. Electrochem. Soc. 151 (2004) A196: the electrodes' fitted open-circuit
/// potentials composed into the full cell with the electrode capacities and lithium balance of
/// PyBaMM's `Ramadass2004` parameter set, charged to its 4.20 V cut-off, as energy fractions
/// above 2.90 V (`lab/scripts/battery/liion_ocv.py` prints it). A resting-voltage table
/// (∫OCV dq): its packs count energy at the open-circuit voltage
/// ([`crate::battery::CircuitParams::ocv_count`]). Not fitted to ProgPy, the peer it is scored
/// against. It replaced a generic NMC datasheet table (3.70 V at 40 %; ProgPy's 18650s rest at
/// 3.79-3.80 V there): an NMC or NCA cell rests lower in mid-charge than this LiCoO2 one, so
/// such a pack declared `liion` reads low at 30-60 % (3.70 V: 17 % here, 40 % on [`LIION_NMC`]);
/// `nmc` names its cathode (docs/src/pack.md, "Energy at landing").
const LIION: [(f64, f64); 53] = [
    (2.90, 0.0),
    (2.92, 0.0005),
    (2.95, 0.0013),
    (2.98, 0.0021),
    (3.00, 0.0027),
    (3.02, 0.0034),
    (3.05, 0.0044),
    (3.07, 0.0052),
    (3.10, 0.0065),
    (3.12, 0.0074),
    (3.15, 0.0089),
    (3.17, 0.01),
    (3.20, 0.0119),
    (3.23, 0.014),
    (3.25, 0.0155),
    (3.27, 0.0171),
    (3.30, 0.0199),
    (3.33, 0.0231),
    (3.35, 0.0254),
    (3.38, 0.0294),
    (3.40, 0.0323),
    (3.42, 0.0356),
    (3.45, 0.0412),
    (3.48, 0.0476),
    (3.50, 0.0526),
    (3.52, 0.0581),
    (3.55, 0.0678),
    (3.58, 0.0796),
    (3.60, 0.0889),
    (3.62, 0.0998),
    (3.65, 0.1203),
    (3.67, 0.1378),
    (3.70, 0.1732),
    (3.73, 0.2263),
    (3.75, 0.2746),
    (3.77, 0.3301),
    (3.80, 0.4128),
    (3.83, 0.4868),
    (3.85, 0.5312),
    (3.88, 0.5918),
    (3.90, 0.6291),
    (3.92, 0.6644),
    (3.95, 0.7139),
    (3.97, 0.745),
    (4.00, 0.7891),
    (4.03, 0.8302),
    (4.05, 0.8559),
    (4.08, 0.8919),
    (4.10, 0.914),
    (4.12, 0.9346),
    (4.15, 0.9623),
    (4.17, 0.9786),
    (4.20, 1.0),
];

/// Li-ion NMC: the open-circuit voltage of the LG M50 21700 (NMC811 / graphite-SiOx) of
/// C.-H. Chen, F. Brosa Planella, K. O'Regan, D. Gastol, W. D. Widanage, E. Kendrick,
/// "Development of Experimental Techniques for Parameterization of Multi-scale Lithium-ion
/// Battery Models", J. Electrochem. Soc. 167 (2020) 080534: the electrodes' measured
/// potentials composed into the full cell with PyBaMM's `Chen2020` set, as energy fractions
/// above 2.90 V (`lab/scripts/battery/lab_round9_circuit.py --ocv-table` prints it). A nickel
/// cathode rests lower in mid-charge than LiCoO2 (3.70 V is 40 % here, 17 % on [`LIION`]); an
/// NCA cell is nearer this curve than that one.
const LIION_NMC: [(f64, f64); 27] = [
    (2.90, 0.0),
    (2.95, 0.0038),
    (3.00, 0.0083),
    (3.05, 0.0139),
    (3.10, 0.0209),
    (3.15, 0.03),
    (3.20, 0.0416),
    (3.25, 0.0547),
    (3.30, 0.0679),
    (3.35, 0.0813),
    (3.40, 0.0974),
    (3.45, 0.1246),
    (3.50, 0.1791),
    (3.55, 0.2302),
    (3.60, 0.2769),
    (3.65, 0.3359),
    (3.70, 0.4036),
    (3.75, 0.4609),
    (3.80, 0.516),
    (3.85, 0.5788),
    (3.90, 0.6294),
    (3.95, 0.6769),
    (4.00, 0.7362),
    (4.05, 0.7947),
    (4.10, 0.9126),
    (4.15, 0.9784),
    (4.20, 1.0),
];

/// LiFePO4 default: the low-rate OCV of an LFP cell (3.65 V full, 2.5 V empty; the long
/// plateau at 3.25-3.35 V) as LFP datasheets and the published OCV tests show it
/// (e.g. A123 ANR26650M1-B datasheet; Plett, *Battery Management Systems* vol. 1, 2015,
/// ch. 2's LFP OCV). Approximate: the plateau makes SoC from voltage weak, and the band
/// says so ([`Chemistry::soc_band_pct`]).
const LIFEPO4: [(f64, f64); 10] = [
    (2.50, 0.0),
    (2.90, 0.03),
    (3.10, 0.08),
    (3.20, 0.15),
    (3.25, 0.30),
    (3.28, 0.50),
    (3.30, 0.70),
    (3.33, 0.90),
    (3.40, 0.97),
    (3.65, 1.00),
];

impl Chemistry {
    /// Every chemistry known.
    pub const ALL: [Chemistry; 5] = [
        Chemistry::LiPo,
        Chemistry::LiHv,
        Chemistry::LiIon,
        Chemistry::LiIonNmc,
        Chemistry::LiFePo4,
    ];

    /// The chemistry a name gives as users and the flag write it (`lipo`, `lihv`,
    /// `li-ion`, `liion`, `lion`, `nmc`, `nca`, `lifepo4`, `lfp`; any case).
    pub fn parse_loose(name: &str) -> Option<Self> {
        match name
            .to_ascii_lowercase()
            .replace(['-', '_', ' '], "")
            .as_str()
        {
            "lipo" => Some(Chemistry::LiPo),
            "lihv" | "lipohv" => Some(Chemistry::LiHv),
            "liion" | "lion" | "lco" => Some(Chemistry::LiIon),
            "nmc" | "nca" | "liionnmc" | "liionnca" => Some(Chemistry::LiIonNmc),
            "lifepo4" | "lfp" | "life" => Some(Chemistry::LiFePo4),
            _ => None,
        }
    }

    /// The chemistry MAVLink's MAV_BATTERY_TYPE names (BATTERY_STATUS / BATTERY_INFO
    /// `type`): LiPo, LiFe, Li-ion; None for unknown, NiMH and anything else.
    pub fn from_mav_type(t: u8) -> Option<Self> {
        match t {
            1 => Some(Chemistry::LiPo),
            2 => Some(Chemistry::LiFePo4),
            3 => Some(Chemistry::LiIon),
            _ => None,
        }
    }

    /// Li-ion of either cathode (`liion`, `nmc`): one window, one circuit's priors.
    pub fn is_li_ion(self) -> bool {
        matches!(self, Chemistry::LiIon | Chemistry::LiIonNmc)
    }

    /// The lowest loaded voltage a cell of this chemistry can show, V: a modelled voltage
    /// under it is not a voltage (Li-ion cells are specified to 2.5 V under load, LiFePO4
    /// to 2.0 V).
    pub fn loaded_min_v(self) -> f64 {
        match self {
            Chemistry::LiFePo4 => 2.0,
            _ => 2.5,
        }
    }

    /// As the config writes it: `lipo`, `lihv`, `liion`, `nmc`, `lifepo4`.
    pub fn name(self) -> &'static str {
        self.into()
    }
    /// The inverse of [`Chemistry::name`] (exact, lower case).
    pub fn from_name(name: &str) -> Option<Self> {
        name.parse().ok()
    }
    /// Full-charge resting voltage per cell.
    pub fn full_v(self) -> f64 {
        match self {
            Chemistry::LiPo | Chemistry::LiIon | Chemistry::LiIonNmc => 4.20,
            Chemistry::LiHv => 4.35,
            Chemistry::LiFePo4 => 3.65,
        }
    }
    /// Nominal voltage per cell (labels, Wh ratings).
    pub fn nominal_v(self) -> f64 {
        match self {
            Chemistry::LiPo => 3.70,
            Chemistry::LiHv => 3.80,
            Chemistry::LiIon | Chemistry::LiIonNmc => 3.60,
            Chemistry::LiFePo4 => 3.20,
        }
    }
    /// Lowest plausible *resting* voltage per cell (the empty end of the OCV table).
    pub fn floor_v(self) -> f64 {
        match self {
            Chemistry::LiPo => 3.27,
            Chemistry::LiHv => 3.30,
            Chemistry::LiIon | Chemistry::LiIonNmc => 2.90,
            Chemistry::LiFePo4 => 2.50,
        }
    }
    /// Default normalised OCV curve (SoC 0..1 vs V/cell) and its source: LiPo the hobby
    /// table (below), LiHV the TB48D shape fitted on the M100 data set (Rodrigues et al.
    /// 2021), Li-ion the Sony US-18650's measured OCV (Ramadass et al. 2004), NMC the LG M50's
    /// (Chen et al. 2020), LiFePO4 the LFP table (below).
    pub fn default_curve(self) -> OcvCurve {
        match self {
            Chemistry::LiPo => OcvCurve::from_soc_pairs(&LIPO),
            Chemistry::LiIon => OcvCurve::from_soc_pairs(&LIION),
            Chemistry::LiIonNmc => OcvCurve::from_soc_pairs(&LIION_NMC),
            Chemistry::LiHv => OcvCurve::tb48d().normalized(),
            Chemistry::LiFePo4 => OcvCurve::from_soc_pairs(&LIFEPO4),
        }
    }
}

/// Tolerance above `full_v` for meter error / fresh-off-charger surface charge.
pub const FULL_TOL_V: f64 = 0.05;

/// Every cell count `n` (1..=16) whose per-cell voltage `v_rest/n` lies in
/// `[floor_v, full_v + FULL_TOL_V]`. Compares `v_rest` against `n·bound` (no division, no
/// `ceil`: 12.6/4.2 is 3.0000000000000004 in f64, so `ceil` would say 4). More than one
/// result means the count is ambiguous from voltage alone; empty means implausible input.
pub fn cell_candidates(chem: Chemistry, v_rest: f64) -> Vec<u32> {
    if !v_rest.is_finite() || v_rest <= 0.0 {
        return Vec::new();
    }
    let eps = 1e-9;
    (1u32..=16)
        .filter(|&n| {
            let nf = f64::from(n);
            v_rest >= nf * chem.floor_v() - eps && v_rest <= nf * (chem.full_v() + FULL_TOL_V) + eps
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The cathode matters in mid-charge: a nickel cell resting at 3.70 V is 40 % full, a
    /// LiCoO2 one 17 %; the ends agree (the same 4.20 V / 2.90 V window).
    #[test]
    fn an_nmc_pack_reads_its_own_curve_not_the_lco_one() {
        let (lco, nmc) = (
            Chemistry::LiIon.default_curve(),
            Chemistry::LiIonNmc.default_curve(),
        );
        assert!((nmc.soc(3.70) - 0.40).abs() < 0.01, "{}", nmc.soc(3.70));
        assert!((lco.soc(3.70) - 0.17).abs() < 0.01, "{}", lco.soc(3.70));
        for v in [2.9, 4.2] {
            assert!((nmc.soc(v) - lco.soc(v)).abs() < 1e-9);
        }
        assert_eq!(Chemistry::LiIonNmc.full_v(), Chemistry::LiIon.full_v());
    }

    #[test]
    fn full_3s_lipo_is_three_cells() {
        assert_eq!(cell_candidates(Chemistry::LiPo, 12.6), vec![3]);
    }

    #[test]
    fn exact_full_packs() {
        for n in 1..=12u32 {
            let lipo = cell_candidates(Chemistry::LiPo, 4.2 * f64::from(n));
            assert!(lipo.contains(&n), "LiPo {n}: {lipo:?}");
            let lihv = cell_candidates(Chemistry::LiHv, 4.35 * f64::from(n));
            assert!(lihv.contains(&n), "LiHV {n}: {lihv:?}");
            // never fewer cells than the truth (a full nS can also look like a low (n+1)S)
            assert_eq!(lipo.first(), Some(&n), "LiPo {n}: {lipo:?}");
        }
        // full 6S LiHV (4.35) is also a plausible 7S at 3.73 V/cell: ambiguous, say so
        assert_eq!(cell_candidates(Chemistry::LiHv, 26.1), vec![6, 7]);
    }

    #[test]
    fn ambiguous_and_garbage() {
        // 13.2 V is a low 4S or an over-full 3S LiPo? 3S max 12.75 -> 4S only
        assert_eq!(cell_candidates(Chemistry::LiPo, 13.2), vec![4]);
        // Li-ion at 8.8 V: 2S (4.4 no) -> 3S at 2.93 V ok, 2S at 4.4 too high
        assert_eq!(cell_candidates(Chemistry::LiIon, 8.8), vec![3]);
        // 25 V LiPo: 6S (4.17) and 7S (3.57): ambiguous
        assert_eq!(cell_candidates(Chemistry::LiPo, 25.0), vec![6, 7]);
        assert!(cell_candidates(Chemistry::LiPo, f64::NAN).is_empty());
        assert!(cell_candidates(Chemistry::LiPo, 0.0).is_empty());
        assert!(cell_candidates(Chemistry::LiPo, -3.0).is_empty());
    }

    #[test]
    fn default_curves_are_monotone_and_span_window() {
        for c in Chemistry::ALL {
            let k = c.default_curve();
            assert!((k.soc(c.full_v()) - 1.0).abs() < 1e-9, "{c:?}");
            assert!(k.soc(c.floor_v()).abs() < 1e-9, "{c:?}");
            let mut last = -1.0;
            for i in 0..=200 {
                let v = 2.5 + 2.0 * f64::from(i) / 200.0;
                let s = k.soc(v);
                assert!(s >= last - 1e-12);
                last = s;
            }
        }
    }

    /// The names the config and the vehicle store write (strum's derive, as the
    /// hand-written match was): lower case, exact.
    #[test]
    fn names_round_trip() {
        for (c, name) in [
            (Chemistry::LiPo, "lipo"),
            (Chemistry::LiHv, "lihv"),
            (Chemistry::LiIon, "liion"),
            (Chemistry::LiIonNmc, "nmc"),
            (Chemistry::LiFePo4, "lifepo4"),
        ] {
            assert_eq!(Chemistry::parse_loose(name), Some(c));
            assert_eq!(c.name(), name);
            assert_eq!(Chemistry::from_name(name), Some(c));
        }
        assert_eq!(Chemistry::from_name("LiPo"), None);
        assert_eq!(Chemistry::from_name("nimh"), None);
        assert_eq!(Chemistry::parse_loose("Li-ion"), Some(Chemistry::LiIon));
        assert_eq!(Chemistry::parse_loose("LFP"), Some(Chemistry::LiFePo4));
        assert_eq!(Chemistry::parse_loose("NCA"), Some(Chemistry::LiIonNmc));
        assert_eq!(
            Chemistry::parse_loose("Li-ion_NMC"),
            Some(Chemistry::LiIonNmc)
        );
        assert_eq!(Chemistry::parse_loose("nimh"), None);
    }
}
