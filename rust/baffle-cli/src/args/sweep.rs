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
        /// Annulus z-scores to design at (comma-separated; with --bsa or --height-cm/--weight-kg).
        #[arg(long, value_delimiter = ',', allow_negative_numbers = true, required_unless_present = "areas_mm2", conflicts_with = "areas_mm2")]
        pub z_scores: Vec<f64>,
        /// Target areas to design at (mm2, comma-separated), instead of --z-scores.
        #[arg(long, value_delimiter = ',')]
        pub areas_mm2: Vec<f64>,
        /// Instead of --surface: prepare the capped ventricle from these blood pools once (as
        /// `baffle plan`, into --out/prepare); --cfd then runs on each design's extended domain.
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
        /// Also mesh each designed domain and run the quick estimate (`baffle plan --quick`:
        /// from rest to the first flow peak; inflow on the VSD cap, or with --segmentations on
        /// the mid-LV cap of the extended domain): dp, v_max and the verdict per row.
        #[arg(long, requires = "bp")]
        pub cfd: bool,
        /// Blood pressure SBP/DBP (mmHg) for --cfd: the outlet resistance R = MAP / Q_mean.
        #[arg(long, value_parser = parse_bp, requires = "cfd")]
        pub bp: Option<(f64, f64)>,
        /// Heart rate (beats/min) for --cfd; default: the built-in period of 0.682 s.
        #[arg(long, requires = "cfd")]
        pub hr: Option<f64>,
        /// Largest tetrahedron edge of --cfd's meshes (mm); the paper's coarse level, for speed.
        #[arg(long, default_value_t = SweepCfd::default().edge_length_mm, requires = "cfd")]
        pub edge_length_mm: f64,
        /// Cardiac index of --cfd's runs (L/min/m2): the mean flow is BSA x cardiac index.
        #[arg(long, default_value_t = SweepCfd::default().cardiac_index, requires = "cfd")]
        pub cardiac_index: f64,
    }
}
