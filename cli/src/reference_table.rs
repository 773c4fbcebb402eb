//! A reference encoder's own calibrated table (`--ref-table`): what a calibration against it
//! takes out of its readings, and the uncertainty it adds.

use crate::exit::Usage;
use anyhow::Context;
use calib_core::TableMap;
use std::path::Path;

/// The reference's calibrated table (`--ref-table`): its map, and the largest u of its points.
pub struct ReferenceTable {
    /// The reference's error map, a function of its reading.
    pub map: calib_core::ErrorMap,
    /// The largest standard uncertainty of its points, radians (`None`: the table has no
    /// u_arcsec column).
    pub u_max: Option<f64>,
}

impl ReferenceTable {
    /// Reads `--ref-table`: a whole-turn table.
    pub fn read(path: &Path) -> anyhow::Result<Self> {
        if !path.exists() {
            return Err(Usage(format!(
                "--ref-table {}: no such table; check the path",
                path.display()
            ))
            .into());
        }
        let table = calib_io::table::read_table(path)
            .with_context(|| format!("cannot read the reference's table {}", path.display()))?;
        let TableMap::Turn(map) = table.map else {
            return Err(Usage(format!(
                "--ref-table {}: a range table; the reference's table must cover a whole turn",
                path.display()
            ))
            .into());
        };
        Ok(ReferenceTable {
            u_max: table.u.map(|u| u.iter().fold(0.0f64, |m, v| m.max(*v))),
            map,
        })
    }
}
