//! A frame's budget (PLP, section 3): how many triangles it may draw, as a
//! count or as a share of the scene. A budget in milliseconds is turned
//! into a count each frame by whoever measures the draw rate
//! (`farfield_client::budget`), since a traversal neither draws nor times.

use std::fmt;
use std::str::FromStr;

/// How many triangles one frame may draw.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum Budget {
    /// Everything.
    #[default]
    Unlimited,
    /// At most this many.
    Triangles(u64),
    /// At most this percentage (0..=100) of the scene's triangles, rounded
    /// up. Kept as a percentage so `7%` of 100 is 7, not the 8 that
    /// 0.07 * 100 = 7.000000000000001 would round up to.
    Percent(f64),
}

impl Budget {
    /// The budget in triangles for a scene of `scene` triangles.
    pub fn triangles(self, scene: u64) -> u64 {
        match self {
            Self::Unlimited => u64::MAX,
            Self::Triangles(n) => n,
            Self::Percent(p) if p >= 100.0 => u64::MAX,
            // NaN and negatives draw nothing.
            Self::Percent(p) if p.is_nan() || p <= 0.0 => 0,
            // p * scene is exact for whole percentages (scenes under 2^53).
            Self::Percent(p) => (p * scene as f64 / 100.0).ceil() as u64,
        }
    }
}

impl FromStr for Budget {
    type Err = String;

    /// `5%` (a share of the scene), `20000` (triangles) or `all`.
    fn from_str(s: &str) -> Result<Self, String> {
        let s = s.trim();
        if s == "all" {
            return Ok(Self::Unlimited);
        }
        if let Some(p) = s.strip_suffix('%') {
            return match p.trim().parse::<f64>() {
                Ok(v) if v.is_finite() && v >= 0.0 => Ok(Self::Percent(v)),
                _ => Err(format!("budget {s} is not a non-negative percentage")),
            };
        }
        s.parse::<u64>()
            .map(Self::Triangles)
            .map_err(|_| format!("budget {s} is not a triangle count, a percentage (5%) or all"))
    }
}

impl fmt::Display for Budget {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Unlimited => write!(f, "all"),
            Self::Triangles(n) => write!(f, "{n}"),
            Self::Percent(p) => write!(f, "{p}%"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn budgets_parse_and_resolve() {
        let b: Budget = "5%".parse().expect("percent");
        assert_eq!(b, Budget::Percent(5.0));
        assert_eq!(b.triangles(500_000), 25_000);
        assert_eq!(b.triangles(1), 1, "a share rounds up");
        assert_eq!("0%".parse::<Budget>().map(|b| b.triangles(100)), Ok(0));
        assert_eq!(
            "100%".parse::<Budget>().map(|b| b.triangles(7)),
            Ok(u64::MAX)
        );
        assert_eq!("1200".parse::<Budget>(), Ok(Budget::Triangles(1200)));
        assert_eq!("all".parse::<Budget>(), Ok(Budget::Unlimited));
        for bad in ["-1%", "x", "1.5", "nan%", ""] {
            assert!(bad.parse::<Budget>().is_err(), "{bad}");
        }
        assert_eq!(Budget::Percent(f64::NAN).triangles(10), 0);
        assert_eq!(Budget::Percent(5.0).to_string(), "5%");
        // Shares whose fraction does not round-trip through binary.
        for (share, scene, expected) in [("7%", 100, 7), ("14%", 50, 7), ("28%", 200, 56)] {
            let b: Budget = share.parse().expect("percent");
            assert_eq!(b.triangles(scene), expected, "{share} of {scene}");
            assert_eq!(b.to_string(), share);
        }
    }
}
