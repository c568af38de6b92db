//! `baffle template`'s arguments.

use super::design::Frame;
use baffle_plan::template_cmd::{TemplateMethod as PlanMethod, TemplateSettings};
use baffle_plan::design_cmd::FaceLabels;
use clap::Args;
use std::path::PathBuf;

super::settings_args! {
    #[derive(Args)]
    pub struct TemplateArgs into TemplateSettings {
        #[arg(long)]
        pub domain: PathBuf,
        #[arg(long)]
        pub points: PathBuf,
        #[arg(long)]
        pub out: PathBuf,
        #[arg(long, default_value_t = TemplateSettings::default().dpi)]
        pub dpi: f64,
        #[arg(long, default_value = "")]
        pub label: String,
        #[arg(long)]
        pub date: Option<String>,
        #[arg(long, value_enum, default_value_t = Frame::from(TemplateSettings::default().surface_frame))]
        pub surface_frame: Frame,
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
