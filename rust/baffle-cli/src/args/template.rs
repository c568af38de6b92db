//! `baffle template`'s arguments.

use super::design::Frame;
use baffle_plan::template_cmd::{TemplateMethod as PlanMethod, TemplateSettings};
use baffle_plan::design_cmd::FaceLabels;
use clap::Args;
use std::path::PathBuf;

super::settings_args! {
    #[derive(Args)]
    pub struct TemplateArgs into TemplateSettings {
        /// Designed domain (domain.vtp from `baffle design`): ModelFaceID baffle, VSD and aortic caps.
        #[arg(long)]
        pub domain: PathBuf,
        /// The surgeon's suture points (.mrk.json, .fcsv, CSV or JSON), numbered on the template.
        #[arg(long)]
        pub points: PathBuf,
        /// Output: .pdf (A4, vector), .svg (A4, viewBox in mm) or .png (A4 at --dpi, the DPI
        /// stored in the file). A JSON report with the perimeter and distortion figures is
        /// written beside it (<stem>-report.json).
        #[arg(long)]
        pub out: PathBuf,
        /// Resolution of a .png template (dots per inch).
        #[arg(long, default_value_t = TemplateSettings::default().dpi)]
        pub dpi: f64,
        /// Patient label printed on the template.
        #[arg(long, default_value = "")]
        pub label: String,
        /// Date printed on the template (default: today, UTC).
        #[arg(long)]
        pub date: Option<String>,
        /// Frame of the domain (the points are converted into it), as for `baffle design`.
        #[arg(long, value_enum, default_value_t = Frame::from(TemplateSettings::default().surface_frame))]
        pub surface_frame: Frame,
        /// Flattening: lscm (conformal; keeps the seam's angles and edge lengths best) or
        /// arap (LSCM then as-rigid-as-possible; smaller largest area change).
        #[arg(long, value_enum, default_value_t = TemplateMethod::from(TemplateSettings::default().method))]
        pub method: TemplateMethod,
        // --baffle-label, --vsd-label, --aortic-label.
        #[command(flatten)]
        pub labels: TemplateLabelArgs,
    }
}

/// The domain's ModelFaceIDs the template reads (the wall's is not needed).
#[derive(Args)]
pub struct TemplateLabelArgs {
    #[arg(long, default_value_t = TemplateSettings::default().labels.baffle)]
    pub baffle_label: i32,
    #[arg(long, default_value_t = TemplateSettings::default().labels.vsd_cap)]
    pub vsd_label: i32,
    #[arg(long, default_value_t = TemplateSettings::default().labels.aortic_cap)]
    pub aortic_label: i32,
}

impl From<TemplateLabelArgs> for FaceLabels {
    fn from(a: TemplateLabelArgs) -> Self {
        FaceLabels { baffle: a.baffle_label, vsd_cap: a.vsd_label, aortic_cap: a.aortic_label, ..TemplateSettings::default().labels }
    }
}

super::value_enum! {
    /// The flattening of `baffle template --method`.
    TemplateMethod mirrors PlanMethod { Lscm, Arap }
}
