//! `prepare`'s check of its own caps by a second method (issue 27): each written cap is
//! re-measured against its opening traced on the segmentations themselves
//! ([`crate::openings`]), not on the union the caps were cut from. The VSD cap must
//! close the LV-RV opening, the aortic-annulus cap the RV-aorta opening.
//!
//! Where the pools only touch, the opening's rim is where their gap is what the union
//! bridges. The closing of radius r fills the wedge between two pools that part at an
//! angle to at least where they are r apart and at most where they are 2r apart (its
//! diameter), and the voxelization joins them up to one voxel h farther: the union's
//! rim lies where the gap is between `r` and `2r + h`. The cap's area must lie between
//! the openings traced at those two gaps, widened by the band the union's surface may
//! lie off a pool where the closing rounds the crease (perimeter x (r + h/2)); its centroid within `r + 2h`
//! of the centroids' path between those two openings, and every rim point that far
//! from the nearer of the two rims, where a cut moved away from the interface adds its
//! reported move to both.

use crate::openings::largest_opening;
use crate::separation::CutSeparation;
use baffle_core::analyses::self_check::SelfCheck;
use baffle_core::geometry::spatial::{closest_point_on_segment, TriangleBvh};
use baffle_core::{TriMesh, Vec3};

/// The gaps (mm) between the pools at which the union's rim can lie, from the closing
/// radius and the voxel.
#[derive(Clone, Copy, Debug)]
pub struct BridgedGap {
    pub voxel_mm: f64,
    pub closing_radius_mm: f64,
}

impl BridgedGap {
    fn least_mm(&self) -> f64 {
        self.closing_radius_mm
    }
    fn most_mm(&self) -> f64 {
        2.0 * self.closing_radius_mm + self.voxel_mm
    }
    /// How far the union's surface may lie off a pool (mm): the closing rounds a crease
    /// within its radius, the voxels add half their edge.
    fn surface_offset_mm(&self) -> f64 {
        self.closing_radius_mm + 0.5 * self.voxel_mm
    }
    /// How far a cap's centroid and rim may lie from the opening (mm).
    fn position_tolerance_mm(&self) -> f64 {
        self.closing_radius_mm + 2.0 * self.voxel_mm
    }
}

/// One cap to check: its label and name, the pools whose opening it closes (the one
/// reaching into `rv`), and how far its cut was moved off the interface (mm).
pub struct CapToCheck<'a> {
    pub label: i32,
    pub name: &'static str,
    pub pair: &'static str,
    pub pool: &'a TriMesh,
    pub moved_mm: f64,
}

/// The caps' checks against the openings of `caps[k].pool` into `rv`.
pub fn cap_checks(mesh: &TriMesh, rv: &TriMesh, rv_bvh: &TriangleBvh, caps: &[CapToCheck], gap: BridgedGap) -> Vec<SelfCheck> {
    caps.iter().flat_map(|cap| check_cap(mesh, rv, rv_bvh, cap, gap)).collect()
}

/// The caps of prepare's result: VSD (the LV's opening into the RV) and aortic annulus
/// (the aorta's), with the moves `separation` reports.
pub fn prepared_cap_checks(
    mesh: &TriMesh,
    pools: &crate::BloodPools,
    rv_bvh: &TriangleBvh,
    labels: (i32, i32),
    separation: &CutSeparation,
    gap: BridgedGap,
) -> Vec<SelfCheck> {
    let caps = [
        CapToCheck { label: labels.0, name: "VSD cap", pair: "LV-RV", pool: &pools.lv, moved_mm: separation.vsd_cut_moved_into_lv_mm },
        CapToCheck { label: labels.1, name: "aortic-annulus cap", pair: "RV-aorta", pool: &pools.aorta, moved_mm: separation.aortic_cut_moved_into_aorta_mm },
    ];
    cap_checks(mesh, &pools.rv, rv_bvh, &caps, gap)
}

fn check_cap(mesh: &TriMesh, rv: &TriMesh, rv_bvh: &TriangleBvh, cap: &CapToCheck, gap: BridgedGap) -> Vec<SelfCheck> {
    let name = |what: &str| format!("{} {what} the {} opening", cap.name, cap.pair);
    let (inner, outer) = (largest_opening(cap.pool, rv, rv_bvh, gap.least_mm()), largest_opening(cap.pool, rv, rv_bvh, gap.most_mm()));
    let Some((c, _, area_mm2)) = mesh.label_centroid_normal(cap.label) else {
        return vec![SelfCheck::at_least(&format!("{} present", cap.name), 0.0, 1.0, "triangles", format!("no triangle carries label {}", cap.label))];
    };
    let (Some(inner), Some(outer)) = (inner, outer) else {
        let detail = format!("the segmentations' {} surfaces come no closer than {:.2} mm: there is no opening to close", cap.pair, gap.most_mm());
        return vec![SelfCheck::at_least(&name("on"), 0.0, 1.0, "openings", detail)];
    };
    let at = |p: Vec3| format!("({:.1}, {:.1}, {:.1})", p.x, p.y, p.z);
    let traced = format!(
        "openings traced on the segmentations where the {} gap is {:.2}-{:.2} mm (closing radius {:.2} mm, voxel {:.2} mm)",
        cap.pair,
        gap.least_mm(),
        gap.most_mm(),
        gap.closing_radius_mm,
        gap.voxel_mm
    );
    let tolerance = gap.position_tolerance_mm() + cap.moved_mm;
    let moved = if cap.moved_mm > 0.0 { format!(" + the cut's move {:.1} mm", cap.moved_mm) } else { String::new() };

    let (lo, hi) = (inner.area_mm2.min(outer.area_mm2), inner.area_mm2.max(outer.area_mm2));
    let band_mm2 = gap.surface_offset_mm() * outer.perimeter_mm;
    let (area_lo, area_hi) = (lo - band_mm2, hi + band_mm2);
    // Outside [lo, hi] by this fraction of the range's nearer end (0 inside).
    let excess_pct = 100.0 * ((area_lo - area_mm2).max(area_mm2 - area_hi).max(0.0)) / if area_mm2 < area_lo { area_lo } else { area_hi };
    let area = SelfCheck::at_most(
        &name("area against"),
        excess_pct,
        0.0,
        "%",
        format!(
            "cap {area_mm2:.1} mm2 at {}; the opening spans {lo:.1}-{hi:.1} mm2, {band_mm2:.1} mm2 either way allowed (rim x (closing radius + half a voxel)); \
             the value is how far the cap lies outside {area_lo:.1}-{area_hi:.1} mm2; {traced}",
            at(c)
        ),
    );

    let (path, _) = closest_point_on_segment(&c, &inner.centroid_mm, &outer.centroid_mm);
    let centroid = SelfCheck::at_most(
        &name("centroid on"),
        (c - path).norm(),
        tolerance,
        "mm",
        format!(
            "cap centroid {} vs the opening's {} -> {} (tolerance closing radius + 2 voxels{moved}); {traced}",
            at(c),
            at(inner.centroid_mm),
            at(outer.centroid_mm)
        ),
    );

    let (rim_off_mm, worst) = cap_rim(mesh, cap.label)
        .into_iter()
        .map(|p| (inner.distance_to_rim_mm(&p).min(outer.distance_to_rim_mm(&p)), p))
        .fold((0.0, c), |a, b| if b.0 > a.0 { b } else { a });
    let rim = SelfCheck::at_most(
        &name("rim on"),
        rim_off_mm,
        tolerance,
        "mm",
        format!("farthest rim point {} from the opening's rim (tolerance closing radius + 2 voxels{moved}); {traced}", at(worst)),
    );
    vec![centroid, area, rim]
}

/// The rim points of cap `label` in `mesh`.
fn cap_rim(mesh: &TriMesh, label: i32) -> Vec<Vec3> {
    let cap = mesh.with_labels(|l| l == label);
    cap.boundary_loops().unwrap_or_default().concat().iter().map(|&v| cap.points[v as usize]).collect()
}
