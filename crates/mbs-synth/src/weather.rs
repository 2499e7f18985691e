//! The five MBS20K weathers and the lighting preset of each.

use std::fmt;
use std::str::FromStr;

use serde::{Deserialize, Serialize};

use crate::vec3::Vec3;

/// A weather of MBS20K (conventions §3); names match the dataset's folder names.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
pub enum Weather {
    /// Clear sky at night: dim moonlight, lit windows.
    ClearNight,
    /// Clear sky at noon: strong sun from high up.
    #[default]
    ClearNoon,
    /// Clear sky at sunset: low, warm sun and an orange horizon.
    ClearSunset,
    /// Overcast noon: soft light, grey sky.
    CloudyNoon,
    /// Moderate rain at noon: dull light, fog, darker wet ground.
    MidRainyNoon,
}

impl Weather {
    /// All weathers, in the order of the dataset's statistics table.
    pub const ALL: [Weather; 5] = [
        Weather::ClearNight,
        Weather::ClearNoon,
        Weather::ClearSunset,
        Weather::CloudyNoon,
        Weather::MidRainyNoon,
    ];

    /// The folder name used by MBS20K.
    pub fn name(self) -> &'static str {
        match self {
            Weather::ClearNight => "ClearNight",
            Weather::ClearNoon => "ClearNoon",
            Weather::ClearSunset => "ClearSunset",
            Weather::CloudyNoon => "CloudyNoon",
            Weather::MidRainyNoon => "MidRainyNoon",
        }
    }

    /// The lighting preset of this weather.
    pub(crate) fn lighting(self) -> Lighting {
        match self {
            Weather::ClearNoon => Lighting::clear_noon(),
            Weather::ClearSunset => Lighting::clear_sunset(),
            Weather::ClearNight => Lighting::clear_night(),
            Weather::CloudyNoon => Lighting::cloudy_noon(),
            Weather::MidRainyNoon => Lighting::mid_rainy_noon(),
        }
    }
}

impl Lighting {
    /// ClearNoon: strong sun from high up, a blue sky.
    fn clear_noon() -> Lighting {
        Lighting {
            sun_dir: Vec3::new(0.35, -0.85, -0.4).normalized(),
            sun: [0.75, 0.72, 0.66],
            ambient_sky: [0.36, 0.40, 0.48],
            ambient_ground: [0.22, 0.20, 0.18],
            sky_zenith: [0.22, 0.42, 0.82],
            sky_horizon: [0.68, 0.78, 0.92],
            clouds: 0.25,
            cloud_colour: [0.95, 0.95, 0.97],
            fog_m: 700.0,
            window_glow: 0.0,
            wetness: 0.0,
        }
    }

    /// ClearSunset: a low, warm sun and an orange horizon.
    fn clear_sunset() -> Lighting {
        Lighting {
            sun_dir: Vec3::new(-0.8, -0.22, -0.5).normalized(),
            sun: [0.95, 0.58, 0.30],
            ambient_sky: [0.30, 0.26, 0.32],
            ambient_ground: [0.20, 0.15, 0.12],
            sky_zenith: [0.28, 0.32, 0.58],
            sky_horizon: [0.98, 0.60, 0.34],
            clouds: 0.3,
            cloud_colour: [0.98, 0.70, 0.55],
            fog_m: 500.0,
            window_glow: 0.15,
            wetness: 0.0,
        }
    }

    /// ClearNight: dim moonlight, a dark sky, lit windows.
    fn clear_night() -> Lighting {
        Lighting {
            sun_dir: Vec3::new(0.3, -0.8, -0.45).normalized(),
            sun: [0.13, 0.15, 0.22],
            ambient_sky: [0.07, 0.08, 0.12],
            ambient_ground: [0.05, 0.045, 0.04],
            sky_zenith: [0.01, 0.02, 0.06],
            sky_horizon: [0.06, 0.07, 0.12],
            clouds: 0.15,
            cloud_colour: [0.12, 0.12, 0.16],
            fog_m: 900.0,
            window_glow: 0.85,
            wetness: 0.0,
        }
    }

    /// CloudyNoon: soft light and a grey sky.
    fn cloudy_noon() -> Lighting {
        Lighting {
            sun_dir: Vec3::new(0.35, -0.85, -0.4).normalized(),
            sun: [0.22, 0.22, 0.23],
            ambient_sky: [0.58, 0.60, 0.63],
            ambient_ground: [0.30, 0.29, 0.28],
            sky_zenith: [0.56, 0.58, 0.62],
            sky_horizon: [0.76, 0.77, 0.80],
            clouds: 0.85,
            cloud_colour: [0.84, 0.85, 0.87],
            fog_m: 450.0,
            window_glow: 0.0,
            wetness: 0.0,
        }
    }

    /// MidRainyNoon: dull light, fog and darker wet ground.
    fn mid_rainy_noon() -> Lighting {
        Lighting {
            sun_dir: Vec3::new(0.35, -0.85, -0.4).normalized(),
            sun: [0.12, 0.12, 0.13],
            ambient_sky: [0.44, 0.46, 0.50],
            ambient_ground: [0.22, 0.22, 0.23],
            sky_zenith: [0.40, 0.42, 0.46],
            sky_horizon: [0.58, 0.60, 0.64],
            clouds: 1.0,
            cloud_colour: [0.50, 0.51, 0.54],
            fog_m: 160.0,
            window_glow: 0.05,
            wetness: 0.45,
        }
    }
}

impl fmt::Display for Weather {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// An unknown weather name.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error(
    "unknown weather {0:?}; expected one of ClearNight, ClearNoon, ClearSunset, CloudyNoon, MidRainyNoon"
)]
pub struct ParseWeatherError(pub String);

impl FromStr for Weather {
    type Err = ParseWeatherError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Weather::ALL
            .into_iter()
            .find(|w| w.name() == s)
            .ok_or_else(|| ParseWeatherError(s.to_owned()))
    }
}

/// Light and atmosphere of a weather (colours in display space, 0..1).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Lighting {
    /// Unit vector from a surface towards the sun (or moon).
    pub(crate) sun_dir: Vec3,
    /// Colour times intensity of the directional light.
    pub(crate) sun: [f32; 3],
    /// Ambient light from above (upward-facing surfaces get all of it).
    pub(crate) ambient_sky: [f32; 3],
    /// Ambient light bounced from the ground (downward-facing surfaces).
    pub(crate) ambient_ground: [f32; 3],
    /// Sky colour high above the horizon.
    pub(crate) sky_zenith: [f32; 3],
    /// Sky colour at the horizon, also the fog colour.
    pub(crate) sky_horizon: [f32; 3],
    /// Cloud cover in [0, 1].
    pub(crate) clouds: f64,
    /// Cloud colour.
    pub(crate) cloud_colour: [f32; 3],
    /// Depth (m) at which fog reaches half strength.
    pub(crate) fog_m: f64,
    /// Emission of lit windows.
    pub(crate) window_glow: f32,
    /// How much darker and smoother wet ground looks, in [0, 1].
    pub(crate) wetness: f32,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip() {
        for w in Weather::ALL {
            assert_eq!(w.to_string().parse::<Weather>(), Ok(w));
            let json = serde_json::to_string(&w).unwrap();
            assert_eq!(json, format!("\"{w}\""));
        }
        let err = "Sunny".parse::<Weather>().unwrap_err();
        assert!(err.to_string().contains("ClearNoon"));
    }
}
