//! The scene file's participation settings (`[participation]`) and planners' viewpoints
//! (`[[viewpoints]]`), issue #14.

use super::camera_params::CameraParams;
use crate::fields::Mapping;
use crate::render::style::{LayerStyle, PartialStyle};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use utoipa::ToSchema;

/// When a new comment becomes public.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize, Serialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum Moderation {
    /// Post-moderation: public at once; moderators hide afterwards.
    #[default]
    Post,
    /// Pre-moderation: pending until a moderator approves it.
    Pre,
}

/// A token bucket: `burst` actions at once, refilled at `per_minute`.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, Serialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct RateLimit {
    /// Actions allowed at once (the bucket's size), at least 1.
    pub burst: u32,
    /// Actions regained per minute, above 0.
    pub per_minute: f64,
}

/// `[participation.rate_limit]`: the buckets of citizens' writes (comments, likes, reports).
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, Serialize, ToSchema)]
#[serde(default, deny_unknown_fields)]
pub struct RateLimits {
    /// Per author token.
    pub per_token: RateLimit,
    /// Per client address.
    pub per_address: RateLimit,
}

impl Default for RateLimits {
    fn default() -> RateLimits {
        RateLimits {
            per_token: RateLimit { burst: 10, per_minute: 6.0 },
            per_address: RateLimit { burst: 30, per_minute: 30.0 },
        }
    }
}

/// `[participation]`: how comments are moderated and limited.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize, ToSchema)]
#[serde(default, deny_unknown_fields)]
pub struct ParticipationConfig {
    /// `post` (default: public at once) or `pre` (pending until approved).
    pub moderation: Moderation,
    /// The categories a comment may have (default idea, concern, question, other).
    pub categories: Vec<String>,
    /// Longest comment text in characters (default 1000).
    pub max_text_chars: usize,
    /// Reports that hide a comment until a moderator looks at it (default 3).
    pub report_hide_threshold: u32,
    /// Rate limits of citizens' writes.
    pub rate_limit: RateLimits,
}

impl Default for ParticipationConfig {
    fn default() -> ParticipationConfig {
        ParticipationConfig {
            moderation: Moderation::Post,
            categories: ["idea", "concern", "question", "other"].map(String::from).to_vec(),
            max_text_chars: 1000,
            report_hide_threshold: 3,
            rate_limit: RateLimits::default(),
        }
    }
}

impl ParticipationConfig {
    /// Checks the values; the error names the key.
    pub fn validate(&self) -> Result<(), String> {
        if !(1..=100_000).contains(&self.max_text_chars) {
            return Err("participation.max_text_chars must be within 1..=100000".into());
        }
        if self.report_hide_threshold == 0 {
            return Err("participation.report_hide_threshold must be at least 1".into());
        }
        if let Some(bad) = self.categories.iter().find(|c| !is_name(c)) {
            return Err(format!(
                "participation.categories: {bad:?} must be 1-40 characters of letters, digits, '-' or '_'"
            ));
        }
        for (key, limit) in [("per_token", self.rate_limit.per_token), ("per_address", self.rate_limit.per_address)] {
            if limit.burst == 0 || !(limit.per_minute.is_finite() && limit.per_minute > 0.0) {
                return Err(format!(
                    "participation.rate_limit.{key} needs burst >= 1 and per_minute > 0 (got {} and {})",
                    limit.burst, limit.per_minute
                ));
            }
        }
        Ok(())
    }
}

/// Whether `text` is a short identifier: 1–40 ASCII letters, digits, `-` or `_` (category
/// names).
fn is_name(text: &str) -> bool {
    (1..=40).contains(&text.len()) && text.chars().all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_')
}

/// Whether `text` may name a viewpoint: 1–80 characters, no control characters, no `/`
/// (names are path segments of `/api/viewpoints/{name}`).
pub fn is_viewpoint_name(text: &str) -> bool {
    (1..=80).contains(&text.chars().count()) && !text.chars().any(|c| c.is_control() || c == '/')
}

/// A named view that planners prepare and citizens jump to: a camera (as in the render
/// body), a style or preset, layer styles, data mappings, a time and a caption. In the scene
/// file as `[[viewpoints]]`, over the admin API as `PUT /api/viewpoints/{name}`.
#[derive(Debug, Clone, Default, PartialEq, Deserialize, Serialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct Viewpoint {
    /// Unique name (1–80 characters, no `/`).
    pub name: String,
    /// What the view shows, in a sentence for citizens.
    #[serde(default)]
    pub caption: String,
    /// The camera, as `camera` in the body of `POST /api/render`.
    #[serde(default)]
    pub camera: CameraParams,
    /// A style preset.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub preset: Option<String>,
    /// Style fields over the preset.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(value_type = Option<Object>)]
    pub style: Option<PartialStyle>,
    /// Styles of single layers, as in the render body.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(value_type = Option<Object>)]
    pub layer_styles: Option<BTreeMap<String, LayerStyle>>,
    /// Data-layer mappings, as in the render body.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mappings: Option<Vec<Mapping>>,
    /// ISO 8601 time of the data layers.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub time: Option<String>,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_validate_and_bad_values_name_their_key() {
        assert_eq!(ParticipationConfig::default().validate(), Ok(()));
        let parsed: ParticipationConfig =
            toml::from_str("moderation = \"pre\"\n[rate_limit.per_token]\nburst = 2\nper_minute = 1.5\n")
                .expect("toml");
        assert_eq!(parsed.moderation, Moderation::Pre);
        assert_eq!(parsed.rate_limit.per_token, RateLimit { burst: 2, per_minute: 1.5 });
        assert_eq!(parsed.categories.len(), 4);
        let cases = [
            ("max_text_chars = 0", "max_text_chars"),
            ("report_hide_threshold = 0", "report_hide_threshold"),
            ("categories = [\"<b>\"]", "categories"),
            ("[rate_limit.per_address]\nburst = 0\nper_minute = 1.0", "per_address"),
        ];
        for (text, key) in cases {
            let config: ParticipationConfig = toml::from_str(text).expect(text);
            assert!(config.validate().expect_err(text).contains(key), "{text}");
        }
        assert!(toml::from_str::<ParticipationConfig>("moderation = \"later\"").is_err());
        assert!(is_viewpoint_name("Planned woodland") && !is_viewpoint_name("a/b") && !is_viewpoint_name(""));
    }
}
