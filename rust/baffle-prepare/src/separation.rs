//! Keeping the VSD and aortic-annulus openings apart. Where the aorta also touches the
//! LV (as over a subaortic VSD, common in DORV), the two interface loops share a rim on
//! the union of the pools, and a plane through either loop also cuts the other opening:
//! the clip cannot separate them. The cuts are then moved, each parallel to its plane and
//! away from the RV (the VSD cut into the LV, the annulus cut up the aortic root), by the
//! smallest total distance on a grid of `COARSE_STEP_MM` that gives two clean openings at
//! least a clearance apart, then by `FINE_STEP_MM` less where that is still clean (every
//! clip of the wide union is a full split of it, so the fine grid is searched only there).
//! The result's caps then lie that far from the interfaces (the kept band between them is
//! LV or aortic wall), and the report says by how much. Parallel moves keep each cap
//! facing as its opening does (the design's tunnel runs cap to cap); tilting a cut or
//! trimming it to part of its plane would leave a non-planar or partial rim.

use crate::clip::{clip_between, Clipped, Cut};
use crate::interfaces::{InterfaceLoop, Structure};
use baffle_core::geometry::numerics::pca::{polygon_vector_area, Plane};
use baffle_core::{TriMesh, Vec3};
use rayon::prelude::*;

/// Steps of the move search (mm).
pub const COARSE_STEP_MM: f64 = 1.0;
pub const FINE_STEP_MM: f64 = 0.5;
/// Largest move of either cut (mm): less than an infant's aortic root to the
/// sinotubular junction (about one annulus diameter), where `extend` ends it.
pub const MAX_MOVE_MM: f64 = 9.0;
/// The union follows each pool within the closing and the smoothing; a rim farther than
/// this (mm) from the pool its cap closes (the LV for the VSD cap, the aorta for the
/// annulus cap) runs over another pool, and the cap would close that one too.
pub const RIM_OFF_POOL_MM: f64 = 1.0;
/// How a refusal says that a moved cut was wider than its opening.
const WIDENED: &str = "closes more than its opening";

/// How the two openings were kept apart (all distances in mm).
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct CutSeparation {
    /// Smallest distance between the VSD and aortic interface loops as found (before any move).
    pub interface_loops_gap_mm: f64,
    /// How far the VSD cut lies beyond the VSD loop's plane, into the LV.
    pub vsd_cut_moved_into_lv_mm: f64,
    /// How far the annulus cut lies beyond the aortic loop's plane, up the aortic root.
    pub aortic_cut_moved_into_aorta_mm: f64,
    /// Smallest distance between the two openings' rims after the clip.
    pub rim_gap_mm: f64,
    /// The rims must lie at least this far apart (one remesh edge).
    pub clearance_mm: f64,
    /// Cut pairs clipped before this one was accepted.
    pub cuts_tried: usize,
}

impl CutSeparation {
    pub fn moved(&self) -> bool {
        self.vsd_cut_moved_into_lv_mm > 0.0 || self.aortic_cut_moved_into_aorta_mm > 0.0
    }

    /// One line for the user: how far apart the openings are, and any move.
    pub fn summary(&self) -> String {
        let gap = format!("openings {:.2} mm apart (clearance {:.2} mm)", self.rim_gap_mm, self.clearance_mm);
        if !self.moved() {
            return gap;
        }
        format!(
            "the VSD and aortic interfaces come within {:.2} mm of each other, so the cuts were moved: the VSD cut {:.1} mm into the LV, \
             the aortic cut {:.1} mm up the aortic root; {gap}",
            self.interface_loops_gap_mm, self.vsd_cut_moved_into_lv_mm, self.aortic_cut_moved_into_aorta_mm
        )
    }
}

/// One cut pair's clip, its rims on their pools, and their gap (mm).
struct Attempt {
    clipped: Clipped,
    planes: [Plane; 2],
    rim_gap_mm: f64,
}

/// The clip of the two openings: the kept wall, the planes it was cut along (VSD, aortic), and how.
pub struct Separated {
    pub clipped: Clipped,
    pub planes: [Plane; 2],
    pub report: CutSeparation,
}

/// (VSD move, aortic move) pairs on the search grid, by total distance, the aortic
/// move first at equal totals (it keeps the VSD cap at the VSD, where the baffle starts).
pub fn move_grid(step_mm: f64) -> Vec<(f64, f64)> {
    let n = (MAX_MOVE_MM / step_mm).round() as usize;
    let mut pairs: Vec<(usize, usize)> = (0..=n).flat_map(|i| (0..=n).map(move |j| (i, j))).collect();
    pairs.sort_by_key(|&(i, j)| (i + j, i));
    pairs.into_iter().map(|(i, j)| (i as f64 * step_mm, j as f64 * step_mm)).collect()
}

/// The coarse grid's first accepted pair, then the pairs one fine step below it; where
/// the coarse grid fails because a moved cut widened, the fine grid below that.
pub fn separate_by_moves(
    union: &TriMesh,
    loops: [&InterfaceLoop; 2],
    beyond: [&Structure; 2],
    rv_center: Vec3,
    clearance_mm: f64,
    snap_mm: f64,
) -> Result<Separated, String> {
    let search = |moves: &[(f64, f64)]| separate_openings(union, loops, beyond, rv_center, moves, clearance_mm, snap_mm);
    let coarse_grid = move_grid(COARSE_STEP_MM);
    let coarse = match search(&coarse_grid) {
        Ok(coarse) => coarse,
        // A coarse step may straddle the depth where the pool widens: the fine grid's
        // other pairs, below it (a VSD cut 0.5 mm in may still close the VSD).
        Err(e) if e.contains(WIDENED) => {
            let fine: Vec<(f64, f64)> = move_grid(FINE_STEP_MM).into_iter().filter(|m| !coarse_grid.contains(m)).collect();
            return search(&fine).map_err(|fine_error| format!("{e}; on the {FINE_STEP_MM} mm grid: {fine_error}"));
        }
        Err(e) => return Err(e),
    };
    let (v, a) = (coarse.report.vsd_cut_moved_into_lv_mm, coarse.report.aortic_cut_moved_into_aorta_mm);
    let mut finer: Vec<(f64, f64)> = [(v - FINE_STEP_MM, a - FINE_STEP_MM), (v - FINE_STEP_MM, a), (v, a - FINE_STEP_MM)]
        .into_iter()
        .filter(|m| m.0 >= 0.0 && m.1 >= 0.0)
        .collect();
    finer.sort_by(|x, y| (x.0 + x.1).total_cmp(&(y.0 + y.1)).then(x.0.total_cmp(&y.0)));
    match search(&finer) {
        Ok(mut fine) => {
            fine.report.cuts_tried += coarse.report.cuts_tried;
            Ok(fine)
        }
        Err(_) => Ok(coarse),
    }
}

/// The first of `moves` whose cuts clip `union` into one part with two openings at least
/// `clearance_mm` apart, each rim on the pool `beyond` it (LV, aorta); each cut moves along
/// its loop's normal away from `rv_center`.
/// Otherwise the error says what the unmoved cuts did and the best the moves reached.
pub fn separate_openings(
    union: &TriMesh,
    loops: [&InterfaceLoop; 2],
    beyond: [&Structure; 2],
    rv_center: Vec3,
    moves: &[(f64, f64)],
    clearance_mm: f64,
    snap_mm: f64,
) -> Result<Separated, String> {
    let interface_loops_gap_mm = min_distance_mm(&loops[0].points_mm, &loops[1].points_mm);
    let away = loops.map(|lp| outward_normal(&lp.plane, rv_center));
    // Err((Some(k), why)): clean, but moved cut k closes more than its opening.
    let attempt = |&(vsd_mm, aortic_mm): &(f64, f64)| -> Result<Attempt, (Option<usize>, String)> {
        let shift = [vsd_mm, aortic_mm];
        let planes = [0, 1].map(|k| Plane { centroid: loops[k].plane.centroid + shift[k] * away[k], ..loops[k].plane });
        let moved: [Vec<Vec3>; 2] = [0, 1].map(|k| loops[k].points_mm.iter().map(|p| p + shift[k] * away[k]).collect());
        let names = ["VSD", "aortic annulus"];
        let cuts = [0, 1].map(|k| Cut { name: names[k], plane: planes[k], loop_mm: &moved[k] });
        let clipped = clip_between(union, &cuts, snap_mm).map_err(|e| (None, e))?;
        let rim = |k: usize| -> Vec<Vec3> { clipped.rims[k].iter().map(|&v| clipped.mesh.points[v as usize]).collect() };
        if let Some((k, (d, p))) = [0, 1].map(|k| (k, farthest_off_mm(&rim(k), beyond[k]))).into_iter().find(|(_, off)| off.0 > RIM_OFF_POOL_MM) {
            return Err((None, format!(
                "the {} cut runs {d:.2} mm off the {} near ({:.1}, {:.1}, {:.1}), over another pool (at most {RIM_OFF_POOL_MM} mm)",
                names[k], ["LV", "aorta"][k], p.x, p.y, p.z
            )));
        }
        if let Some(k) = [0, 1].into_iter().find(|&k| shift[k] > 0.0 && wider_than_its_opening(&rim(k), loops[k], clearance_mm)) {
            let (area, opening) = (polygon_vector_area(&rim(k)).norm(), polygon_vector_area(&loops[k].points_mm).norm());
            return Err((Some(k), format!(
                "the {} cut moved {:.1} mm {} closes {area:.1} mm2 there, more than the {opening:.1} mm2 opening and its rim band of {clearance_mm:.2} mm: \
                 the cap would close {} wall as if it were the opening",
                names[k], shift[k], ["into the LV", "up the aorta"][k], ["LV", "aortic"][k]
            )));
        }
        let rim_gap_mm = min_distance_mm(&rim(0), &rim(1));
        Ok(Attempt { clipped, planes, rim_gap_mm })
    };
    let mut first_error = None;
    let mut widened: (usize, Option<String>) = (0, None);
    let mut closest: Option<(f64, (f64, f64))> = None;
    // A few cut pairs at a time in parallel, judged in order: the first accepted is the
    // same as a sequential search's.
    let batch = rayon::current_num_threads().max(1);
    // A cut that widened at some move is not tried farther: the pool has widened by
    // then, and a deeper cap would leave that wider band of it inside the ventricle.
    let mut widened_at = [f64::INFINITY; 2];
    let mut pending = moves.iter().copied();
    let mut tried = 0;
    loop {
        let chunk: Vec<(f64, f64)> = pending.by_ref().filter(|m| m.0 < widened_at[0] && m.1 < widened_at[1]).take(batch).collect();
        if chunk.is_empty() {
            break;
        }
        let outcomes: Vec<Result<Attempt, (Option<usize>, String)>> = chunk.par_iter().map(attempt).collect();
        for (outcome, &(vsd_mm, aortic_mm)) in outcomes.into_iter().zip(&chunk) {
            if vsd_mm >= widened_at[0] || aortic_mm >= widened_at[1] {
                continue;
            }
            tried += 1;
            match outcome {
                Ok(a) if a.rim_gap_mm >= clearance_mm => {
                    let report = CutSeparation {
                        interface_loops_gap_mm,
                        vsd_cut_moved_into_lv_mm: vsd_mm,
                        aortic_cut_moved_into_aorta_mm: aortic_mm,
                        rim_gap_mm: a.rim_gap_mm,
                        clearance_mm,
                        cuts_tried: tried,
                    };
                    return Ok(Separated { clipped: a.clipped, planes: a.planes, report });
                }
                Ok(a) => {
                    if closest.is_none_or(|(gap, _)| a.rim_gap_mm > gap) {
                        closest = Some((a.rim_gap_mm, (vsd_mm, aortic_mm)));
                    }
                    first_error.get_or_insert_with(|| format!("the openings are {:.2} mm apart, less than the clearance {clearance_mm:.2} mm", a.rim_gap_mm));
                }
                Err((Some(k), e)) => {
                    widened_at[k] = widened_at[k].min([vsd_mm, aortic_mm][k]);
                    widened.0 += 1;
                    widened.1.get_or_insert(e);
                }
                Err((None, e)) => {
                    first_error.get_or_insert(e);
                }
            }
        }
    }
    let widened = widened.1.map(|e| {
        format!("; {} clean pairs were not taken, nor any cut moved farther, because a moved cut {WIDENED}, the first: {e}", widened.0)
    });
    Err(refusal(moves, interface_loops_gap_mm, first_error, closest) + &widened.unwrap_or_default())
}

/// Why no cut pair was accepted, with the moves tried and the best gap they reached.
fn refusal(moves: &[(f64, f64)], loops_gap_mm: f64, first_error: Option<String>, closest: Option<(f64, (f64, f64))>) -> String {
    let first = first_error.unwrap_or_else(|| "no cut was tried".into());
    if moves.len() <= 1 {
        return first;
    }
    let (max_vsd, max_aortic) = moves.iter().fold((0.0f64, 0.0f64), |(a, b), m| (a.max(m.0), b.max(m.1)));
    let step_mm = moves.iter().flat_map(|m| [m.0, m.1]).filter(|&d| d > 0.0).fold(f64::INFINITY, f64::min);
    let best = match closest {
        Some((gap, (v, a))) => format!("the widest clean pair of openings was {gap:.2} mm apart (VSD cut {v:.1} mm into the LV, aortic cut {a:.1} mm up the aorta)"),
        None => "no pair of cuts gave one part with two openings".into(),
    };
    format!(
        "{first}; the VSD and aortic interfaces come within {loops_gap_mm:.2} mm of each other, and moving the VSD cut up to {max_vsd:.1} mm into \
         the LV and the aortic cut up to {max_aortic:.1} mm up the aorta ({} pairs, {step_mm} mm steps) did not separate them: {best}",
        moves.len()
    )
}

/// Whether a moved cut's rim spans more than the loop it was moved from plus a band of
/// `band_mm` along that loop: the pool widens behind the opening (an LV behind a small
/// VSD, the sinuses above the annulus), and a planar cap there would close the pool's
/// section, not the opening (issue 27: a VSD cap 7 times the VSD's area).
fn wider_than_its_opening(rim: &[Vec3], opening: &InterfaceLoop, band_mm: f64) -> bool {
    let n = opening.points_mm.len();
    let perimeter_mm: f64 = (0..n).map(|i| (opening.points_mm[(i + 1) % n] - opening.points_mm[i]).norm()).sum();
    polygon_vector_area(rim).norm() > polygon_vector_area(&opening.points_mm).norm() + band_mm * perimeter_mm
}

/// The plane's unit normal turned away from `rv_center` (out of the RV through the opening).
fn outward_normal(plane: &Plane, rv_center: Vec3) -> Vec3 {
    if (plane.centroid - rv_center).dot(&plane.normal) >= 0.0 {
        plane.normal
    } else {
        -plane.normal
    }
}

/// The point of `rim` farthest from `pool`'s surface, and that distance (mm).
fn farthest_off_mm(rim: &[Vec3], pool: &Structure) -> (f64, Vec3) {
    rim.iter()
        .filter_map(|&p| pool.bvh.closest_point(pool.surface, p).map(|h| (h.distance_mm, p)))
        .fold((0.0, Vec3::zeros()), |a, b| if b.0 > a.0 { b } else { a })
}

/// Smallest distance between a point of `a` and a point of `b` (mm).
pub fn min_distance_mm(a: &[Vec3], b: &[Vec3]) -> f64 {
    a.iter().flat_map(|p| b.iter().map(move |q| (p - q).norm())).fold(f64::INFINITY, f64::min)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_move_grid_starts_unmoved_and_prefers_the_aortic_move() {
        let grid = move_grid(COARSE_STEP_MM);
        assert_eq!(grid[0], (0.0, 0.0));
        assert_eq!(grid[1], (0.0, COARSE_STEP_MM), "aortic move first at equal totals");
        assert_eq!(grid[2], (COARSE_STEP_MM, 0.0));
        let n = (MAX_MOVE_MM / COARSE_STEP_MM) as usize + 1;
        assert_eq!(grid.len(), n * n);
        let totals: Vec<f64> = grid.iter().map(|m| m.0 + m.1).collect();
        assert!(totals.windows(2).all(|w| w[0] <= w[1]), "by total distance");
    }

    /// Loops on a tube of radius 2 along z in the planes z = 3 + 0.6 y and z = 5 - 0.6 y:
    /// they cross on the tube near y = 1.67, so the unmoved cuts touch.
    #[test]
    fn crossing_cuts_on_a_tube_are_moved_apart_by_the_smallest_total() {
        use crate::shapes::capped_tube;
        use baffle_core::geometry::numerics::pca::best_fit_plane;
        use baffle_core::geometry::spatial::TriangleBvh;
        let tube = capped_tube(Vec3::zeros(), Vec3::new(0.0, 0.0, 10.0), 2.0, 40, 64);
        let bvh = TriangleBvh::new(&tube).unwrap();
        let pool = Structure { label: 1, surface: &tube, bvh: &bvh };
        let ring = |z0: f64, slope: f64| {
            let points_mm: Vec<Vec3> = (0..32)
                .map(|k| {
                    let a = k as f64 * std::f64::consts::PI / 16.0;
                    Vec3::new(2.0 * a.cos(), 2.0 * a.sin(), z0 + slope * 2.0 * a.sin())
                })
                .collect();
            InterfaceLoop { plane: best_fit_plane(&points_mm), points_mm }
        };
        let (vsd, aortic) = (ring(3.0, 0.6), ring(5.0, -0.6));
        let middle = Vec3::new(0.0, 0.0, 4.0);
        let search = |moves: &[(f64, f64)]| separate_openings(&tube, [&vsd, &aortic], [&pool, &pool], middle, moves, 0.5, 1e-6);
        assert!(search(&[(0.0, 0.0)]).is_err(), "the unmoved cuts touch");
        let s = search(&move_grid(FINE_STEP_MM)).unwrap_or_else(|e| panic!("{e}"));
        let r = &s.report;
        // The rims are 0.4 mm apart along z at y = 2 the wrong way round; a move d along
        // a normal 31 degrees off z shifts a rim by 1.17 d, so a 0.5 mm gap needs d >= 0.77.
        let total = r.vsd_cut_moved_into_lv_mm + r.aortic_cut_moved_into_aorta_mm;
        assert!((1.0..=1.5).contains(&total) && r.rim_gap_mm >= 0.5 && r.cuts_tried > 3, "{r:?}");
        let moved_z = [3.0 - s.planes[0].centroid.z, s.planes[1].centroid.z - 5.0];
        let expected = [r.vsd_cut_moved_into_lv_mm, r.aortic_cut_moved_into_aorta_mm].map(|d| d * vsd.plane.normal.z.abs());
        assert!((0..2).all(|k| (moved_z[k] - expected[k]).abs() < 1e-9), "moved away from the middle: {moved_z:?} vs {expected:?}");
        assert_eq!(s.clipped.rims.len(), 2);
    }

    #[test]
    fn the_normal_points_away_from_the_rv() {
        let plane = baffle_core::geometry::numerics::pca::best_fit_plane(&[Vec3::new(0.0, 0.0, 5.0), Vec3::new(1.0, 0.0, 5.0), Vec3::new(0.0, 1.0, 5.0), Vec3::new(1.0, 1.0, 5.0)]);
        assert!(outward_normal(&plane, Vec3::zeros()).z > 0.99);
        assert!(outward_normal(&plane, Vec3::new(0.0, 0.0, 9.0)).z < -0.99);
    }
}
