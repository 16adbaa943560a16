//! Plots of a run from its executed-path log: the axes over time, and the axial section
//! the executed moves cut against the job's target.

use crate::config::job::Job;
use crate::geometry::linkage::Ring;
use crate::judge::measure::{Motion, VerifyError};
use crate::judge::svg::{Plot, Series};
use crate::judge::verify::{self, CheckError};
use crate::log::{Event, Read};

/// The axial section the logged executed moves cut, against `job`'s target (swept by `ring`,
/// the ring the program was planned with: [`verify::target`]), with the error magnified so
/// that Δ draws as a twentieth of the pitch, around the middle of the groove. Needs executed
/// moves, which a simulated controller logs; rapids are positioning and are left out, as the
/// simulator's Δ guard leaves them.
pub fn section_plot(log: &Read, job: &Job, ring: Ring) -> Result<Plot, CheckError> {
    let target = verify::target(job, ring)?;
    let mut motion = Motion::empty();
    for (i, r) in log.records.iter().enumerate() {
        if let Event::Executed {
            from,
            to,
            rapid: false,
            ..
        } = &r.event
        {
            motion.push(*from, *to, i + 1)?;
        }
    }
    if !motion.is_turning() {
        return Err(VerifyError::NoTurning.into());
    }
    let pitch = job.groove.lead / f64::from(job.groove.starts);
    let middle = job.groove.z_start + job.groove.length / 2.0;
    Ok(target.section_plot(&motion, middle, verify::magnification(job.cut.delta, pitch)))
}

/// X, Z and C over time, from the status reports: one plot per axis.
pub fn axis_plots(log: &Read) -> Vec<Plot> {
    let names = [("X", "mm"), ("Z", "mm"), ("C", "degrees")];
    let colours = ["steelblue", "darkgreen", "darkorange"];
    (0..3)
        .map(|k| Plot {
            title: format!("{} over time", names[k].0),
            x_label: "time, s".into(),
            y_label: format!("{}, {}", names[k].0, names[k].1),
            series: vec![Series {
                label: names[k].0.into(),
                colour: colours[k],
                points: log
                    .records
                    .iter()
                    .filter_map(|r| match &r.event {
                        Event::Status { pos, .. } => Some((r.t, pos[k])),
                        _ => None,
                    })
                    .collect(),
            }],
            equal_scale: false,
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::log::Record;

    #[test]
    fn axis_plots_follow_the_status_reports() {
        let read = Read {
            records: vec![
                Record {
                    t: 0.3,
                    event: Event::Status {
                        state: "Run".into(),
                        pos: [0.5, 0.0, 0.0],
                        blocks_free: Some(34),
                        rx_free: Some(1000),
                        line: None,
                    },
                },
                Record {
                    t: 0.9,
                    event: Event::Executed {
                        line: Some(1),
                        times: [0.2, 0.8],
                        from: [0.0; 3],
                        to: [1.0, 0.0, 0.0],
                        rapid: false,
                    },
                },
            ],
            torn_tail: false,
            skipped: Vec::new(),
        };
        let plots = axis_plots(&read);
        assert_eq!(plots.len(), 3);
        assert_eq!(plots[0].series[0].points, vec![(0.3, 0.5)]);
    }
}
