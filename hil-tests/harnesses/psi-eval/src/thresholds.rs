//! The quality thresholds a committed model promises, read from its model card
//! (`models/MODEL_CARD.md`), so the card and the regression test cannot disagree.
//!
//! The card holds one fenced block tagged `thresholds`, one bound per line:
//!
//! ```text
//! mae <= 0.10
//! smp_success >= 0.60
//! ```
//!
//! Metric names are the fields of [`QualityReport`](crate::metrics::QualityReport).

use crate::metrics::QualityReport;

/// One bound on one metric.
#[derive(Debug, Clone, PartialEq)]
pub struct Bound {
    /// Metric name (a [`QualityReport`] field).
    pub metric: String,
    /// `true` for `<=`, `false` for `>=`.
    pub at_most: bool,
    /// The limit.
    pub limit: f64,
}

/// Why the thresholds could not be read.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ThresholdError {
    /// No ```` ```thresholds ```` block in the card.
    #[error("model card has no ```thresholds block")]
    NoBlock,
    /// A line in the block is not `metric <= number` or `metric >= number`.
    #[error("model card thresholds line {line}: cannot parse `{text}` (want `metric <= number`)")]
    BadLine {
        /// 1-based line number in the card.
        line: usize,
        /// The line.
        text: String,
    },
    /// The metric is not one of the report's.
    #[error("model card thresholds line {line}: unknown metric `{metric}`")]
    UnknownMetric {
        /// 1-based line number in the card.
        line: usize,
        /// The name found.
        metric: String,
    },
}

/// The value of metric `name` in `report`, if it exists.
pub fn metric(report: &QualityReport, name: &str) -> Option<f64> {
    Some(match name {
        "mae" => report.mae,
        "brier" => report.brier,
        "ece" => report.ece,
        "f_abs_err" => report.f_abs_err,
        "smp_success" => report.smp_success,
        "smp_success_free" => report.smp_success_free,
        "argmax_success" => report.argmax_success,
        _ => return None,
    })
}

/// Reads the bounds of the card's `thresholds` block.
pub fn parse_model_card(card: &str) -> Result<Vec<Bound>, ThresholdError> {
    let mut in_block = false;
    let mut seen_block = false;
    let mut bounds = Vec::new();
    let probe = QualityReport {
        evaluator: String::new(),
        tasks: 0,
        cells: 0,
        mae: 0.0,
        brier: 0.0,
        ece: 0.0,
        f_abs_err: 0.0,
        f_mean_pred: 0.0,
        f_mean_true: 0.0,
        smp_success: 0.0,
        smp_success_true: 0.0,
        smp_success_free: 0.0,
        smp_success_free_true: 0.0,
        argmax_success: 0.0,
        argmax_success_true: 0.0,
    };
    for (i, raw) in card.lines().enumerate() {
        let line = raw.trim();
        if !in_block {
            if line == "```thresholds" {
                in_block = true;
                seen_block = true;
            }
            continue;
        }
        if line.starts_with("```") {
            in_block = false;
            continue;
        }
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let bad = || ThresholdError::BadLine {
            line: i + 1,
            text: raw.to_owned(),
        };
        let (name, at_most, rest) = if let Some((n, r)) = line.split_once("<=") {
            (n.trim(), true, r)
        } else if let Some((n, r)) = line.split_once(">=") {
            (n.trim(), false, r)
        } else {
            return Err(bad());
        };
        let limit: f64 = rest.trim().parse().map_err(|_| bad())?;
        if !limit.is_finite() {
            return Err(bad());
        }
        if metric(&probe, name).is_none() {
            return Err(ThresholdError::UnknownMetric {
                line: i + 1,
                metric: name.to_owned(),
            });
        }
        bounds.push(Bound {
            metric: name.to_owned(),
            at_most,
            limit,
        });
    }
    if !seen_block {
        return Err(ThresholdError::NoBlock);
    }
    Ok(bounds)
}

/// The bounds `report` violates, as readable lines (empty when all hold).
pub fn violations(report: &QualityReport, bounds: &[Bound]) -> Vec<String> {
    bounds
        .iter()
        .filter_map(|b| {
            let v = metric(report, &b.metric)?;
            let ok = if b.at_most {
                v <= b.limit
            } else {
                v >= b.limit
            };
            (!ok).then(|| {
                format!(
                    "{} = {v:.4} but the model card requires {} {}",
                    b.metric,
                    if b.at_most { "<=" } else { ">=" },
                    b.limit
                )
            })
        })
        .collect()
}

/// Metrics on which `candidate` is not strictly better than `baseline` (lower errors, higher
/// expected success), as readable lines: the issue requires the FCN to beat the binary heuristic
/// on every one.
pub fn not_better_than(candidate: &QualityReport, baseline: &QualityReport) -> Vec<String> {
    let lower = [
        ("mae", candidate.mae, baseline.mae),
        ("brier", candidate.brier, baseline.brier),
        ("ece", candidate.ece, baseline.ece),
        ("f_abs_err", candidate.f_abs_err, baseline.f_abs_err),
    ];
    let mut out: Vec<String> = lower
        .iter()
        .filter(|(_, c, b)| c >= b)
        .map(|(n, c, b)| {
            format!(
                "{n}: {} {c:.4} is not below {} {b:.4}",
                candidate.evaluator, baseline.evaluator
            )
        })
        .collect();
    for (name, c, b) in [
        ("smp_success", candidate.smp_success, baseline.smp_success),
        (
            "smp_success_free",
            candidate.smp_success_free,
            baseline.smp_success_free,
        ),
    ] {
        if c <= b {
            out.push(format!(
                "{name}: {} {c:.4} is not above {} {b:.4}",
                candidate.evaluator, baseline.evaluator
            ));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    const CARD: &str =
        "# card\ntext\n```thresholds\nmae <= 0.1\n# comment\nsmp_success >= 0.5\n```\nmore\n";

    #[test]
    fn parses_the_block() {
        let b = parse_model_card(CARD).unwrap();
        assert_eq!(b.len(), 2);
        assert_eq!(
            b[0],
            Bound {
                metric: "mae".into(),
                at_most: true,
                limit: 0.1
            }
        );
        assert!(!b[1].at_most);
    }

    #[test]
    fn reports_bad_cards() {
        assert_eq!(parse_model_card("no block"), Err(ThresholdError::NoBlock));
        assert!(matches!(
            parse_model_card("```thresholds\nmae < 0.1\n```"),
            Err(ThresholdError::BadLine { line: 2, .. })
        ));
        assert!(matches!(
            parse_model_card("```thresholds\nmae <= x\n```"),
            Err(ThresholdError::BadLine { .. })
        ));
        assert!(matches!(
            parse_model_card("```thresholds\naccuracy >= 0.9\n```"),
            Err(ThresholdError::UnknownMetric { .. })
        ));
    }

    #[test]
    fn finds_violations() {
        let bounds = parse_model_card(CARD).unwrap();
        let mut r = QualityReport {
            evaluator: "x".into(),
            tasks: 1,
            cells: 192,
            mae: 0.05,
            brier: 0.1,
            ece: 0.0,
            f_abs_err: 0.0,
            f_mean_pred: 0.0,
            f_mean_true: 0.0,
            smp_success: 0.7,
            smp_success_true: 0.8,
            smp_success_free: 0.72,
            smp_success_free_true: 0.85,
            argmax_success: 0.9,
            argmax_success_true: 0.95,
        };
        assert!(violations(&r, &bounds).is_empty());
        r.mae = 0.2;
        r.smp_success = 0.4;
        assert_eq!(violations(&r, &bounds).len(), 2);
        let mut better = r.clone();
        better.mae = 0.1;
        better.brier = 0.05;
        better.ece = -1.0;
        better.f_abs_err = -1.0;
        better.smp_success = 0.9;
        better.smp_success_free = 0.95;
        assert!(not_better_than(&better, &r).is_empty());
        better.brier = r.brier;
        assert_eq!(not_better_than(&better, &r).len(), 1);
        better.smp_success_free = r.smp_success_free;
        let lines = not_better_than(&better, &r);
        assert_eq!(lines.len(), 2);
        assert!(lines[1].starts_with("smp_success_free"), "{lines:?}");
    }
}
