//! `baffle sweep`'s arguments.

use super::design::DesignArgs;
use super::plan::parse_bp;
use super::prepare::PrepareSourceArgs;
use baffle_plan::sweep_cmd::{SweepCfd, SweepSettings};
use clap::Args;

super::settings_args! {
    #[derive(Args)]
    #[command(after_help = "Examples:\n  \
        baffle sweep --surface ../shared/data/p2/design_input/capped_ventricle.vtp \\\n      \
        --points ../shared/data/p2/design_input/suture_points.mrk.json --bsa 0.37 --z-scores=-2,-1,0,1,2 --out out/p2-sweep\n  \
        baffle sweep --phantom --areas-mm2 40,60,80,120 --out out/phantom-sweep\n  \
        # with the quick dp estimate per target, on the extended domains (p2: about 2 minutes)\n  \
        baffle sweep --segmentations ../shared/data/p2/segmentations --points ../shared/data/p2/design_input/suture_points.mrk.json \\\n      \
        --bsa 0.37 --z-scores=-2,-1,0,1,2 --cfd --bp 107/78 --hr 133 --out out/p2-sweep-cfd")]
    pub struct SweepArgs into SweepSettings {
        #[command(flatten)]
        pub design: DesignArgs,
        #[arg(long, value_delimiter = ',', allow_negative_numbers = true, required_unless_present = "areas_mm2", conflicts_with = "areas_mm2")]
        pub z_scores: Vec<f64>,
        #[arg(long, value_delimiter = ',')]
        pub areas_mm2: Vec<f64>,
        // --segmentations or --labelmap instead of --surface (SweepSettings::prepare).
        #[command(flatten)]
        pub prepare: PrepareSourceArgs,
        #[command(flatten)]
        pub cfd: CfdArgs,
    }
}

super::settings_args! {
    /// The quick dp estimate per designed target (opt-in: it is minutes, the design seconds).
    #[derive(Args)]
    pub struct CfdArgs into SweepCfd {
        #[arg(long, requires = "bp")]
        pub cfd: bool,
        #[arg(long, value_parser = parse_bp, requires = "cfd")]
        pub bp: Option<(f64, f64)>,
        #[arg(long, requires = "cfd")]
        pub hr: Option<f64>,
        #[arg(long, default_value_t = SweepCfd::default().edge_length_mm, requires = "cfd")]
        pub edge_length_mm: f64,
        #[arg(long, default_value_t = SweepCfd::default().cardiac_index, requires = "cfd")]
        pub cardiac_index: f64,
    }
}
