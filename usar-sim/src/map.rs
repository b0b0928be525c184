//! Maps: a TOML file in the protocol frame (see `docs/maps.md`), with optional OBJ meshes.

use std::path::{Path, PathBuf};

use rapier3d::math::{Pose, Vector};
use rapier3d::prelude::{ColliderBuilder, ColliderHandle};
use serde::Deserialize;
use toml::Spanned;

use super::obj;
use super::scene::{Look, Scene, V3, upright_pose, yaw_rotate};
use super::wind::WindConfig;

/// The maps built into the binary: short name, file name, text.
const EMBEDDED: &[(&str, &str, &str)] = &[
    (
        "empty_room",
        "empty_room.toml",
        include_str!("../maps/empty_room.toml"),
    ),
    ("arena", "arena.toml", include_str!("../maps/arena.toml")),
    ("city", "city.toml", include_str!("../maps/city.toml")),
    ("rescue", "rescue.toml", include_str!("../maps/rescue.toml")),
];

/// OBJ files referenced by the embedded maps.
const EMBEDDED_OBJ: &[(&str, &str)] = &[("tower.obj", include_str!("../maps/tower.obj"))];

/// The short name of the default map.
const DEFAULT_MAP: &str = "empty_room";

pub use crate::scene::LIMIT;

/// Metres: INIT locations are held this far inside [`LIMIT`].
pub const EDGE_MARGIN: f64 = 10.0;

/// The largest map file read (bytes); larger files are refused before reading.
pub const MAX_MAP_FILE: u64 = 16 << 20;

/// The largest OBJ mesh file read (bytes).
pub const MAX_OBJ_FILE: u64 = 64 << 20;

/// What kind of configuration file a [`ConfigError`] is about.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ConfigFile {
    /// A map (docs/maps.md).
    Map,
    /// A robot catalog (docs/robots.md).
    Robots,
}

impl std::fmt::Display for ConfigFile {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Self::Map => "map",
            Self::Robots => "robot catalog",
        })
    }
}

/// Errors reading a configuration file (a map, its meshes, a robot catalog): the one error
/// type of the server's loaders; each names the file, the line and what is wrong.
#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    /// The file could not be read.
    #[error("cannot read {file} file {path}: {error}")]
    Io {
        /// What kind of file.
        file: ConfigFile,
        /// The file.
        path: PathBuf,
        /// Why (shown in this error's text, so not its `source`).
        error: std::io::Error,
    },
    /// An OBJ mesh file that a map names could not be read.
    #[error("cannot read mesh file {path} (named by {map}): {error}")]
    MeshIo {
        /// The OBJ file.
        path: PathBuf,
        /// The map that names it.
        map: PathBuf,
        /// Why.
        error: std::io::Error,
    },
    /// A name that is neither an embedded map nor a file.
    #[error("no map {name:?}: not an embedded map ({known}) and no such file")]
    Unknown {
        /// The name asked for.
        name: String,
        /// The embedded maps' names, comma separated.
        known: String,
    },
    /// The file is not valid.
    #[error("{path}:{line}: {message}")]
    Invalid {
        /// The file (a map, the OBJ file it references, or a robot catalog).
        path: PathBuf,
        /// 1-based line.
        line: usize,
        /// What is wrong.
        message: String,
    },
}

/// A PlayerStart: where `INIT {Start tag}` spawns a robot.
#[derive(Debug, Clone, PartialEq)]
pub struct PlayerStart {
    /// The tag (`{Start ..}` matches it, and the object name, case-insensitively).
    pub tag: String,
    /// The object name (`PlayerStart_<index>` unless given).
    pub name: String,
    /// Metres, protocol frame (z down).
    pub location: [f64; 3],
    /// Radians: roll, pitch, yaw.
    pub rotation: [f64; 3],
}

/// One static solid of the map, in world coordinates.
#[derive(Debug, Clone)]
enum Solid {
    Box {
        center: V3,
        size: V3,
        yaw: f64,
    },
    Cylinder {
        center: V3,
        radius: f64,
        height: f64,
    },
    Mesh {
        vertices: Vec<V3>,
        triangles: Vec<[u32; 3]>,
    },
}

/// One solid of the map seen from above, for pictures and the browser's map.
#[derive(Debug, Clone, PartialEq)]
pub struct Footprint {
    /// Corners in order, world frame `[x, y]` (north, east), metres.
    pub outline: Vec<[f64; 2]>,
    /// The top of the solid (z down: the smallest z), metres.
    pub z_min: f64,
    /// The bottom of the solid, metres.
    pub z_max: f64,
}

/// The classes a `[[victim]]` may have (USARSim's victim pawns).
pub const VICTIM_CLASSES: &[&str] = &["FemaleVictim", "MaleVictim"];

/// The size of a victim without a `size`: a body lying along its yaw, metres.
pub const VICTIM_SIZE: [f64; 3] = [1.7, 0.5, 0.3];

/// A victim or another static object placed in the map: a solid box (robots and rays hit
/// it) with a name, a class and an optional colour; USARTruth lists them.
#[derive(Debug, Clone, PartialEq)]
pub struct Placed {
    /// Unique in the map (`<class>_<index>` unless given).
    pub name: String,
    /// `FemaleVictim` / `MaleVictim` for victims; anything for objects (default `Object`).
    pub class: String,
    /// Whether it is a `[[victim]]` (VictSensor sees it; scoring tools count it).
    pub victim: bool,
    /// Centre of the box, metres, protocol frame (z down).
    pub center: [f64; 3],
    /// Full extents before the yaw, metres.
    pub size: [f64; 3],
    /// About the vertical axis, rad.
    pub yaw: f64,
    /// RGB for pictures and cameras; `None`: the default of its kind.
    pub color: Option<[u8; 3]>,
}

impl Placed {
    /// The four corners seen from above, world frame `[x, y]`.
    pub fn outline(&self) -> Vec<[f64; 2]> {
        box_outline(self.center, self.size, self.yaw)
    }
}

/// A loaded map: level name, time limit, player starts and static geometry.
#[derive(Debug, Clone)]
pub struct Map {
    level: String,
    time_limit: i64,
    starts: Vec<PlayerStart>,
    solids: Vec<Solid>,
    /// Each solid's colour (the same order as `solids`).
    colors: Vec<[u8; 3]>,
    placed: Vec<Placed>,
    wind: Option<WindConfig>,
    /// Where the map is on the Earth (`[geo]`).
    geo: Option<GeoConfig>,
    /// The scene the map builds ([`Map::scene`]).
    built: Built,
}

/// A map's scene, built once for every world that shares the map (worlds copy it and reset
/// to it); emptied when the map changes ([`Map::add_placed`]); a copy of the map starts
/// empty.
#[derive(Debug, Default)]
struct Built(std::sync::OnceLock<std::sync::Arc<Scene>>);

impl Clone for Built {
    fn clone(&self) -> Self {
        Self::default()
    }
}

/// Default colours of map solids (`color` unset): the ground (a slab whose top is at
/// height 0 or below), other slabs (ceilings), walls and other boxes, cylinders, meshes.
pub const GROUND_COLOR: [u8; 3] = [120, 135, 95];
/// See [`GROUND_COLOR`].
pub const CEILING_COLOR: [u8; 3] = [225, 225, 215];
/// See [`GROUND_COLOR`].
pub const WALL_COLOR: [u8; 3] = [205, 190, 165];
/// See [`GROUND_COLOR`].
pub const CYLINDER_COLOR: [u8; 3] = [150, 160, 185];
/// See [`GROUND_COLOR`].
pub const MESH_COLOR: [u8; 3] = [175, 150, 135];
/// Default colour of victims (`[[victim]]` without `color`; the pictures' magenta).
pub const VICTIM_COLOR: [u8; 3] = [214, 40, 200];
/// Default colour of objects (`[[object]]` without `color`).
pub const OBJECT_COLOR: [u8; 3] = [110, 110, 120];

/// The default colour of a box of `size` centred at `center`.
fn box_color(center: V3, size: V3) -> [u8; 3] {
    let slab = size[2] * 5.0 <= size[0].min(size[1]);
    let top = center[2] - size[2] / 2.0;
    match (slab, top >= -0.05) {
        (true, true) => GROUND_COLOR,
        (true, false) => CEILING_COLOR,
        _ => WALL_COLOR,
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawMap {
    /// Required; only the first section ([`sections`]) can hold it.
    level: Option<Spanned<String>>,
    time_limit: Option<i64>,
    #[serde(default)]
    start: Vec<Spanned<RawStart>>,
    #[serde(default, rename = "box")]
    boxes: Vec<Spanned<RawBox>>,
    #[serde(default)]
    cylinder: Vec<Spanned<RawCylinder>>,
    #[serde(default)]
    mesh: Vec<Spanned<RawMesh>>,
    #[serde(default)]
    victim: Vec<Spanned<RawPlaced>>,
    #[serde(default)]
    object: Vec<Spanned<RawPlaced>>,
    #[serde(default)]
    wind: Option<Spanned<WindConfig>>,
    #[serde(default)]
    geo: Option<Spanned<GeoConfig>>,
}

/// Where a map is on the Earth (`[geo]`, docs/maps.md#geo): the geodetic position of its
/// origin (x = y = 0), which a GPS needs, and the Earth's magnetic field a magnetometer
/// measures.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GeoConfig {
    /// Latitude of the origin, degrees, + north (WGS-84); with `longitude`.
    pub latitude: Option<f64>,
    /// Longitude of the origin, degrees, + east (WGS-84); with `latitude`.
    pub longitude: Option<f64>,
    /// The Earth's magnetic field over the map, µT, in the map frame: north (x), east (y),
    /// down (z).
    #[serde(default = "default_field")]
    pub magnetic_field: V3,
}

/// The field a map without `[geo] magnetic_field` has, µT north, east, down: a mid-latitude
/// field (about 20 µT horizontal, 45 µT down: inclination 66°, total 49 µT, as in central
/// Europe or the northern United States; no declination).
pub const DEFAULT_MAGNETIC_FIELD: V3 = [20.0, 0.0, 45.0];

fn default_field() -> V3 {
    DEFAULT_MAGNETIC_FIELD
}

impl Default for GeoConfig {
    fn default() -> Self {
        Self {
            latitude: None,
            longitude: None,
            magnetic_field: DEFAULT_MAGNETIC_FIELD,
        }
    }
}

impl GeoConfig {
    /// The origin's latitude and longitude, degrees, when the map gives both.
    pub fn origin(&self) -> Option<(f64, f64)> {
        self.latitude.zip(self.longitude)
    }

    fn check(&self) -> Result<(), String> {
        let shown = |v: f64| usar_proto::shown::Number(v).to_string();
        match (self.latitude, self.longitude) {
            (Some(lat), Some(lon)) => {
                if !(lat.is_finite() && lat.abs() <= 89.0) {
                    return Err(format!(
                        "`[geo]` latitude must be a number of degrees within ±89 (the GPS's \
                         flat-Earth origin is undefined at the poles), got {}",
                        shown(lat)
                    ));
                }
                if !(lon.is_finite() && lon.abs() <= 180.0) {
                    return Err(format!(
                        "`[geo]` longitude must be a number of degrees within ±180, got {}",
                        shown(lon)
                    ));
                }
            }
            (None, None) => {}
            _ => return Err("`[geo]` gives latitude and longitude together, or neither".into()),
        }
        if !self
            .magnetic_field
            .iter()
            .all(|b| b.is_finite() && b.abs() <= 1000.0)
        {
            return Err(format!(
                "`[geo]` magnetic_field must be three numbers of µT within ±1000, got {:?}",
                self.magnetic_field
            ));
        }
        Ok(())
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawPlaced {
    class: Option<String>,
    name: Option<String>,
    center: V3,
    size: Option<V3>,
    #[serde(default)]
    yaw: f64,
    color: Option<[u8; 3]>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawStart {
    tag: String,
    name: Option<String>,
    location: V3,
    #[serde(default)]
    rotation: V3,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawBox {
    center: V3,
    size: V3,
    #[serde(default)]
    yaw: f64,
    #[serde(default)]
    color: Option<[u8; 3]>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawCylinder {
    center: V3,
    radius: f64,
    height: f64,
    #[serde(default)]
    color: Option<[u8; 3]>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawMesh {
    file: String,
    #[serde(default)]
    offset: V3,
    #[serde(default)]
    yaw: f64,
    #[serde(default = "one")]
    scale: f64,
    #[serde(default)]
    color: Option<[u8; 3]>,
}

fn one() -> f64 {
    1.0
}

/// The 1-based line of byte `offset` in `text`.
pub(crate) fn line_of(text: &str, offset: usize) -> usize {
    let end = offset.min(text.len());
    text.as_bytes()[..end]
        .iter()
        .filter(|&&b| b == b'\n')
        .count()
        + 1
}

/// The longest level name, tag, name or class a map or robot file may give (bytes).
pub const MAX_NAME: usize = 128;

/// Checks a string of a map or robot file that is printed into protocol lines (the level
/// name, a start tag, a part name, a class): not empty, at most [`MAX_NAME`] bytes, and no
/// control character (CR, LF, TAB, NUL, ESC, ...) and no brace, by the protocol's rule for
/// values ([`usar_proto::TextError::check`], the client library's): either would end the
/// line or the group and forge another. A `word` (every such string but the level name)
/// holds no space either: GETSTARTPOSES prints tags space-separated, and names are matched
/// as one token. The error names `what` and the value (escaped).
pub(crate) fn check_name(what: &str, value: &str, word: bool) -> Result<(), String> {
    let shown = || {
        let cut: String = value.chars().take(80).collect();
        let more = if cut.len() < value.len() { "…" } else { "" };
        format!("{cut:?}{more}")
    };
    if value.is_empty() {
        return Err(format!("{what} must not be empty"));
    }
    if let Err(e) = usar_proto::TextError::check("", what, value) {
        return Err(format!(
            "{what} {} holds {}; names may not hold control characters or braces (they would forge protocol lines)",
            shown(),
            e.what
        ));
    }
    if word && value.contains(' ') {
        return Err(format!(
            "{what} {} holds a space; it must be one word",
            shown()
        ));
    }
    if value.starts_with(' ') || value.ends_with(' ') {
        return Err(format!("{what} {} begins or ends with a space", shown()));
    }
    if value.len() > MAX_NAME {
        return Err(format!(
            "{what} {} is {} bytes long, more than the limit of {MAX_NAME}",
            shown(),
            value.len()
        ));
    }
    Ok(())
}

/// The most boxes, cylinders and meshes a map may have (each is a collider of the scene).
pub const MAX_SOLIDS: usize = 200_000;

/// The most victims and objects a map may have together.
pub const MAX_PLACED: usize = 100_000;

/// The bytes a start adds to the GETSTARTPOSES answer: ` tag x,y,z r,p,y` as
/// `World`'s answer prints it (the tag, or the name for the default tag `PlayerStart`; a
/// space before every pose but the first, counted for all here), measured in `scratch`.
fn pose_len(start: &PlayerStart, scratch: &mut String) -> usize {
    let name = if start.tag.eq_ignore_ascii_case("PlayerStart") {
        &start.name
    } else {
        &start.tag
    };
    scratch.clear();
    usar_proto::format::push_fixed_list(scratch, &start.location, 4);
    usar_proto::format::push_fixed_list(scratch, &start.rotation, 4);
    1 + name.len() + 1 + scratch.len() + 1
}

/// The length of the GETSTARTPOSES answer with `count` poses of `poses` bytes in all (as
/// [`pose_len`] counts), its CR LF included: `NFO {StartPoses n} {poses}`.
fn start_poses_len(count: usize, poses: usize) -> usize {
    "NFO {StartPoses ".len() + count.to_string().len() + "} {".len() + poses - 1 + "}\r\n".len()
}

/// How large a section of a TOML file [`sections`] makes before it starts a new one at the
/// next top-level table (bytes).
const SECTION: usize = 64 << 10;

/// Splits TOML text into consecutive sections, each starting at a top-level table header
/// whose key has one part (`[[box]]`, `[wind]`; not `[robot.flight]`, which belongs to the
/// entry before it), of about [`SECTION`] bytes each: (byte offset, text). Each section is
/// a TOML document of its own whose tables are the whole text's, so parsing them one at a
/// time gives the whole text's entries while holding only one section's parse tree (the
/// `toml` crate's takes some 60 times its text). Found with `toml_parser`'s lexer, which
/// holds nothing: brackets inside strings, comments or multi-line values do not count.
pub(crate) fn sections(text: &str) -> Vec<(usize, &str)> {
    use toml_parser::lexer::TokenKind;
    let mut cuts = vec![0];
    let mut line_start = true;
    let mut in_value = false;
    let mut depth = 0usize;
    // A header that may start a section: (its offset, whether its key has a dot so far).
    let mut header: Option<(usize, bool)> = None;
    for token in toml_parser::Source::new(text).lex() {
        let kind = token.kind();
        let start = token.span().start();
        match kind {
            TokenKind::Whitespace | TokenKind::Comment => continue,
            TokenKind::Newline => {
                if depth == 0 {
                    in_value = false;
                }
                line_start = true;
                header = None;
                continue;
            }
            _ => {}
        }
        if in_value {
            match kind {
                TokenKind::LeftSquareBracket | TokenKind::LeftCurlyBracket => depth += 1,
                TokenKind::RightSquareBracket | TokenKind::RightCurlyBracket => {
                    depth = depth.saturating_sub(1);
                }
                _ => {}
            }
        } else if line_start && kind == TokenKind::LeftSquareBracket {
            header = Some((start, false));
        } else if let Some((at, dotted)) = header.as_mut() {
            match kind {
                TokenKind::Dot => *dotted = true,
                TokenKind::RightSquareBracket => {
                    if !*dotted && *at - cuts[cuts.len() - 1] >= SECTION {
                        cuts.push(*at);
                    }
                    header = None;
                }
                _ => {}
            }
        } else if kind == TokenKind::Equals {
            in_value = true;
        }
        line_start = false;
    }
    cuts.push(text.len());
    cuts.windows(2).map(|w| (w[0], &text[w[0]..w[1]])).collect()
}

/// The embedded OBJ file `file`.
fn embedded_obj(file: &str, map: &Path) -> Result<(PathBuf, String), ConfigError> {
    EMBEDDED_OBJ
        .iter()
        .find(|(f, _)| *f == file)
        .map(|(f, text)| (Path::new("maps").join(f), (*text).to_string()))
        .ok_or_else(|| ConfigError::MeshIo {
            path: Path::new("maps").join(file),
            map: map.to_path_buf(),
            error: std::io::ErrorKind::NotFound.into(),
        })
}

/// A mesh loader: relative file name → (path for messages, text).
type ObjSource<'a> = &'a dyn Fn(&str) -> Result<(PathBuf, String), ConfigError>;

impl Map {
    /// Reads a map file; OBJ files are looked up relative to it.
    /// Files past [`MAX_MAP_FILE`] (or meshes past [`MAX_OBJ_FILE`]) are refused unread.
    pub fn from_file(path: &Path) -> Result<Self, ConfigError> {
        let text = read_text(path, MAX_MAP_FILE)
            .map_err(|e| e.into_config_error(ConfigFile::Map, path, None))?;
        let dir = path.parent().unwrap_or(Path::new(".")).to_path_buf();
        let map = path.to_path_buf();
        let load = move |file: &str| {
            let obj_path = dir.join(file);
            let text = read_text(&obj_path, MAX_OBJ_FILE)
                .map_err(|e| e.into_config_error(ConfigFile::Map, &obj_path, Some(&map)))?;
            Ok((obj_path, text))
        };
        Self::parse(&text, path, &load)
    }

    /// A map from TOML text (errors name `path`); meshes may name only the embedded OBJ
    /// files. For tools and fuzzing: nothing is read from disk.
    pub fn from_toml(text: &str, path: &Path) -> Result<Self, ConfigError> {
        Self::parse(text, path, &|f: &str| embedded_obj(f, path))
    }

    /// The map a user names: an embedded map (by short name or level name, any case, so
    /// `arena`, `Arena` and `EmptyRoom` all work) or else a map file.
    pub fn lookup(name: &str) -> Result<Self, ConfigError> {
        if let Some(map) = Self::embedded(name) {
            return Ok(map);
        }
        let path = Path::new(name);
        if !path.exists() {
            return Err(ConfigError::Unknown {
                name: name.to_owned(),
                known: Self::embedded_names().join(", "),
            });
        }
        Self::from_file(path)
    }

    /// An embedded map by short name (see [`Map::embedded_names`]) or level name, any case.
    pub fn embedded(name: &str) -> Option<Self> {
        let squash = |s: &str| s.replace('_', "").to_ascii_lowercase();
        let (_, file, text) = EMBEDDED
            .iter()
            .find(|(short, ..)| squash(short) == squash(name))?;
        let path = Path::new("maps").join(file);
        match Self::parse(text, &path, &|f: &str| embedded_obj(f, &path)) {
            Ok(map) => Some(map),
            Err(e) => {
                // Guarded by a unit test; never happens in a released binary.
                tracing::error!(error = %e, "embedded map is invalid");
                None
            }
        }
    }

    /// Short names of the embedded maps.
    pub fn embedded_names() -> &'static [&'static str] {
        &["empty_room", "arena", "city", "rescue"]
    }

    /// The default map (`empty_room`, level `EmptyRoom`).
    pub fn default_map() -> Self {
        Self::embedded(DEFAULT_MAP).unwrap_or_else(|| Self {
            level: "EmptyRoom".to_string(),
            time_limit: 20,
            starts: Vec::new(),
            solids: Vec::new(),
            colors: Vec::new(),
            placed: Vec::new(),
            wind: None,
            geo: None,
            built: Built::default(),
        })
    }

    /// Adds a victim or an object after loading (a scenario's victims drawn at random):
    /// the checks of a `[[victim]]` / `[[object]]` entry (a one-word unique name, finite
    /// numbers within the map's limits, a positive size), and its body, 2 cm smaller on every
    /// side, must not meet a solid or another placed thing. The error says what is wrong.
    pub fn add_placed(&mut self, p: Placed) -> Result<(), String> {
        check_name("name", &p.name, true)?;
        check_name("class", &p.class, true)?;
        if self.placed.iter().any(|o| o.name == p.name) {
            return Err(format!("duplicate name `{}`", p.name));
        }
        finite(&[&p.center, &p.size, &[p.yaw; 3]])?;
        within(&[&p.center, &p.size], LIMIT)?;
        if p.size.iter().any(|&s| s <= 0.0) {
            return Err(format!("size must be positive, got {:?}", p.size));
        }
        if self.box_is_taken(p.center, p.size, p.yaw) {
            return Err(format!(
                "`{}` at {:?} would overlap a solid of the map or a placed thing",
                p.name, p.center
            ));
        }
        self.placed.push(p);
        self.built = Built::default();
        Ok(())
    }

    /// Whether a box (2 cm smaller on every side) meets a solid or a placed thing.
    pub fn box_is_taken(&self, center: V3, size: V3, yaw: f64) -> bool {
        const SLACK: f64 = 0.02;
        let mut scene = Scene::new();
        build_solids(&self.solids, &mut scene);
        for p in &self.placed {
            scene.insert(box_collider(p.center, p.size, p.yaw));
        }
        scene.refit();
        let inner = size.map(|s| (s - 2.0 * SLACK).max(s / 2.0));
        scene.box_overlaps(&box_collider(center, inner, yaw).build())
    }

    /// The victims and objects, victims first, each in file order.
    pub fn placed(&self) -> &[Placed] {
        &self.placed
    }

    /// Where the map is on the Earth (`[geo]`), if it says.
    pub fn geo(&self) -> Option<GeoConfig> {
        self.geo
    }

    /// The map's wind (`[wind]`), if it sets one.
    pub fn wind(&self) -> Option<WindConfig> {
        self.wind
    }

    /// The level name for the NFO line.
    pub fn level(&self) -> &str {
        &self.level
    }

    /// The NFO `TimeLimit` (minutes).
    pub fn time_limit(&self) -> i64 {
        self.time_limit
    }

    /// The player starts, in file order.
    pub fn starts(&self) -> &[PlayerStart] {
        &self.starts
    }

    /// Every solid seen from above: boxes as their four corners, cylinders as 24-gons, each
    /// mesh triangle as itself. Victims and objects are not among them ([`Map::placed`]).
    pub fn footprints(&self) -> Vec<Footprint> {
        let mut out = Vec::new();
        for solid in &self.solids {
            match solid {
                Solid::Box { center, size, yaw } => {
                    out.push(Footprint {
                        outline: box_outline(*center, *size, *yaw),
                        z_min: center[2] - size[2] / 2.0,
                        z_max: center[2] + size[2] / 2.0,
                    });
                }
                Solid::Cylinder {
                    center,
                    radius,
                    height,
                } => out.push(Footprint {
                    outline: (0..24)
                        .map(|i| {
                            let a = f64::from(i) * std::f64::consts::TAU / 24.0;
                            [center[0] + radius * a.cos(), center[1] + radius * a.sin()]
                        })
                        .collect(),
                    z_min: center[2] - height / 2.0,
                    z_max: center[2] + height / 2.0,
                }),
                Solid::Mesh {
                    vertices,
                    triangles,
                } => out.extend(triangles.iter().filter_map(|t| {
                    let v = t.map(|i| vertices.get(i as usize).copied());
                    let [Some(a), Some(b), Some(c)] = v else {
                        return None;
                    };
                    Some(Footprint {
                        outline: vec![[a[0], a[1]], [b[0], b[1]], [c[0], c[1]]],
                        z_min: a[2].min(b[2]).min(c[2]),
                        z_max: a[2].max(b[2]).max(c[2]),
                    })
                })),
            }
        }
        out
    }

    /// The first start whose tag or name equals `key` (case-insensitive).
    pub fn find_start(&self, key: &str) -> Option<&PlayerStart> {
        self.starts
            .iter()
            .find(|s| s.tag.eq_ignore_ascii_case(key) || s.name.eq_ignore_ascii_case(key))
    }

    fn parse(text: &str, path: &Path, load_obj: ObjSource<'_>) -> Result<Self, ConfigError> {
        let invalid = |offset: usize, message: String| ConfigError::Invalid {
            path: path.to_path_buf(),
            line: line_of(text, offset),
            message,
        };
        let mut level: Option<(usize, String)> = None;
        let mut time_limit = 20;
        let mut starts: Vec<PlayerStart> = Vec::new();
        // The length of the GETSTARTPOSES answer's poses so far, and a buffer to measure one.
        let (mut poses_len, mut scratch) = (0, String::new());
        let mut tags = std::collections::HashMap::new();
        let mut names = std::collections::HashSet::new();
        let mut solids = Vec::new();
        let mut colors = Vec::new();
        let mut mesh_bytes = 0;
        let (mut victims, mut objects) = (Vec::new(), Vec::new());
        let mut wind = None;
        let mut geo = None;
        // One section at a time: only one section's parse tree is ever held.
        for (offset, section) in sections(text) {
            let raw: RawMap = toml::from_str(section).map_err(|e| {
                invalid(
                    offset + e.span().map_or(0, |s| s.start),
                    e.message().trim_end().to_string(),
                )
            })?;
            if let Some(entry) = raw.level {
                level = Some((offset + entry.span().start, entry.into_inner()));
            }
            if let Some(t) = raw.time_limit {
                if t < 0 {
                    return Err(invalid(offset, "`time_limit` must not be negative".into()));
                }
                time_limit = t;
            }
            for entry in raw.start {
                let at = offset + entry.span().start;
                let s = entry.into_inner();
                check_name("start tag", &s.tag, true).map_err(|m| invalid(at, m))?;
                if let Some(name) = &s.name {
                    check_name("start name", name, true).map_err(|m| invalid(at, m))?;
                }
                finite(&[&s.location, &s.rotation]).map_err(|m| invalid(at, m))?;
                within(&[&s.location], LIMIT - EDGE_MARGIN).map_err(|m| invalid(at, m))?;
                within(&[&s.rotation], 1000.0).map_err(|m| invalid(at, m))?;
                let name = s
                    .name
                    .unwrap_or_else(|| format!("PlayerStart_{}", starts.len()));
                // Tags and names are matched case-insensitively; a set each keeps this linear.
                let tag_key = s.tag.to_ascii_lowercase();
                let dup = tags.get(&tag_key).copied().or_else(|| {
                    (!names.insert(name.to_ascii_lowercase()))
                        .then(|| {
                            starts
                                .iter()
                                .position(|o: &PlayerStart| o.name.eq_ignore_ascii_case(&name))
                        })
                        .flatten()
                });
                if let Some(dup) = dup {
                    return Err(invalid(
                        at,
                        format!(
                            "duplicate start `{}` (already used by `{}`)",
                            s.tag, starts[dup].tag
                        ),
                    ));
                }
                tags.insert(tag_key, starts.len());
                let start = PlayerStart {
                    tag: s.tag,
                    name,
                    location: s.location,
                    rotation: s.rotation,
                };
                poses_len += pose_len(&start, &mut scratch);
                let line = start_poses_len(starts.len() + 1, poses_len);
                if line > usar_proto::codec::DEFAULT_MAX_LINE {
                    return Err(invalid(
                        at,
                        format!(
                            "too many starts: with start {}, the GETSTARTPOSES answer would be a line of {line} bytes, longer than the protocol's line limit of {} bytes (clients skip longer lines)",
                            starts.len() + 1,
                            usar_proto::codec::DEFAULT_MAX_LINE
                        ),
                    ));
                }
                starts.push(start);
            }
            let full = |at: usize| {
                invalid(
                    at,
                    format!(
                        "more than {MAX_SOLIDS} boxes, cylinders and meshes: a map has at most {MAX_SOLIDS}"
                    ),
                )
            };
            for entry in &raw.boxes {
                let b = entry.get_ref();
                let at = offset + entry.span().start;
                if solids.len() >= MAX_SOLIDS {
                    return Err(full(at));
                }
                finite(&[&b.center, &b.size, &[b.yaw; 3]]).map_err(|m| invalid(at, m))?;
                within(&[&b.center, &b.size], LIMIT).map_err(|m| invalid(at, m))?;
                within(&[&[b.yaw; 3]], 1000.0).map_err(|m| invalid(at, m))?;
                if b.size.iter().any(|&s| s <= 0.0) {
                    return Err(invalid(
                        at,
                        format!("box size must be positive, got {:?}", b.size),
                    ));
                }
                colors.push(b.color.unwrap_or_else(|| box_color(b.center, b.size)));
                solids.push(Solid::Box {
                    center: b.center,
                    size: b.size,
                    yaw: b.yaw,
                });
            }
            for entry in &raw.cylinder {
                let c = entry.get_ref();
                let at = offset + entry.span().start;
                if solids.len() >= MAX_SOLIDS {
                    return Err(full(at));
                }
                finite(&[&c.center, &[c.radius, c.height, 0.0]]).map_err(|m| invalid(at, m))?;
                within(&[&c.center, &[c.radius, c.height, 0.0]], LIMIT)
                    .map_err(|m| invalid(at, m))?;
                if c.radius <= 0.0 || c.height <= 0.0 {
                    return Err(invalid(
                        at,
                        "cylinder radius and height must be positive".into(),
                    ));
                }
                colors.push(c.color.unwrap_or(CYLINDER_COLOR));
                solids.push(Solid::Cylinder {
                    center: c.center,
                    radius: c.radius,
                    height: c.height,
                });
            }
            for entry in &raw.mesh {
                let m = entry.get_ref();
                let at = offset + entry.span().start;
                if solids.len() >= MAX_SOLIDS {
                    return Err(full(at));
                }
                finite(&[&m.offset, &[m.yaw, m.scale, 0.0]]).map_err(|e| invalid(at, e))?;
                within(&[&m.offset, &[m.scale, 0.0, 0.0]], LIMIT).map_err(|e| invalid(at, e))?;
                within(&[&[m.yaw; 3]], 1000.0).map_err(|m| invalid(at, m))?;
                if m.scale <= 0.0 {
                    return Err(invalid(at, "mesh scale must be positive".into()));
                }
                let (obj_path, obj_text) = load_obj(&m.file)?;
                mesh_bytes += obj_text.len() as u64;
                if mesh_bytes > MAX_OBJ_FILE {
                    return Err(invalid(
                        at,
                        format!(
                            "the meshes' OBJ files hold more than {MAX_OBJ_FILE} bytes in all (the limit)"
                        ),
                    ));
                }
                let mesh =
                    obj::parse(&obj_text).map_err(|(line, message)| ConfigError::Invalid {
                        path: obj_path,
                        line,
                        message,
                    })?;
                let vertices: Vec<V3> = mesh
                    .vertices
                    .iter()
                    .map(|&v| {
                        let r = yaw_rotate(m.yaw, [v[0] * m.scale, v[1] * m.scale, v[2] * m.scale]);
                        [r[0] + m.offset[0], r[1] + m.offset[1], r[2] + m.offset[2]]
                    })
                    .collect();
                if let Some(v) = vertices.iter().find(|v| v.iter().any(|x| x.abs() > LIMIT)) {
                    return Err(invalid(
                        at,
                        format!(
                            "mesh `{}` reaches {v:?}, beyond the world's limit of ±{LIMIT} m",
                            m.file
                        ),
                    ));
                }
                colors.push(m.color.unwrap_or(MESH_COLOR));
                solids.push(Solid::Mesh {
                    vertices,
                    triangles: mesh.triangles,
                });
            }
            for (victim, entries) in [(true, raw.victim), (false, raw.object)] {
                for entry in entries {
                    if victims.len() + objects.len() >= MAX_PLACED {
                        return Err(invalid(
                            offset + entry.span().start,
                            format!(
                                "more than {MAX_PLACED} victims and objects: a map has at most {MAX_PLACED}"
                            ),
                        ));
                    }
                    let list = if victim { &mut victims } else { &mut objects };
                    list.push((offset + entry.span().start, entry.into_inner()));
                }
            }
            if let Some(entry) = raw.wind {
                let at = offset + entry.span().start;
                if wind.is_some() {
                    return Err(invalid(at, "`[wind]` is given twice".into()));
                }
                let w = entry.into_inner();
                w.check().map_err(|m| invalid(at, m))?;
                wind = Some(w);
            }
            if let Some(entry) = raw.geo {
                let at = offset + entry.span().start;
                if geo.is_some() {
                    return Err(invalid(at, "`[geo]` is given twice".into()));
                }
                let g = entry.into_inner();
                g.check().map_err(|m| invalid(at, m))?;
                geo = Some(g);
            }
        }
        let Some((level_at, level)) = level else {
            return Err(invalid(0, "missing field `level`".into()));
        };
        check_name("level", &level, false).map_err(|m| invalid(level_at, m))?;
        let placed = placed_entries(&victims, &objects, &solids, &invalid)?;
        Ok(Self {
            level,
            time_limit,
            starts,
            solids,
            colors,
            placed,
            wind,
            geo,
            built: Built::default(),
        })
    }

    /// The scene of the map's solids, victims and objects, its tree fitted: built at the
    /// first call, shared after.
    pub(crate) fn scene(&self) -> std::sync::Arc<Scene> {
        self.built
            .0
            .get_or_init(|| {
                let mut scene = Scene::new();
                self.build(&mut scene);
                scene.refit();
                scene.reserve_leaf();
                std::sync::Arc::new(scene)
            })
            .clone()
    }

    /// Adds the map's solids to the scene, each with its colour and its segmentation id
    /// (1, 2, ... in the file's order of boxes, then cylinders, then meshes), then its
    /// victims and objects (ids after the solids', in the file's order).
    pub(crate) fn build(&self, scene: &mut Scene) {
        scene.geo = self.geo.unwrap_or_default();
        for (index, handle) in build_solids(&self.solids, scene) {
            let segment = u32::try_from(index + 1).unwrap_or(u32::MAX);
            let color = self.colors.get(index).copied().unwrap_or(WALL_COLOR);
            scene.set_look(handle, Look { color, segment });
        }
        for (i, p) in self.placed.iter().enumerate() {
            let handle = scene.insert(box_collider(p.center, p.size, p.yaw));
            let segment = u32::try_from(self.solids.len() + i + 1).unwrap_or(u32::MAX);
            let default = if p.victim { VICTIM_COLOR } else { OBJECT_COLOR };
            let color = p.color.unwrap_or(default);
            scene.set_look(handle, Look { color, segment });
            if p.victim {
                scene.add_victim(handle, p.center, p.size, p.yaw);
            }
        }
    }
}

/// Checks the `[[victim]]` and `[[object]]` entries: classes, names, numbers, and that no
/// victim is inside a wall (its box, 2 cm smaller on every side, meets a solid of the map).
fn placed_entries(
    victims: &[(usize, RawPlaced)],
    objects: &[(usize, RawPlaced)],
    solids: &[Solid],
    invalid: &dyn Fn(usize, String) -> ConfigError,
) -> Result<Vec<Placed>, ConfigError> {
    let mut walls: Option<Scene> = None;
    let mut placed: Vec<Placed> = Vec::with_capacity(victims.len() + objects.len());
    let mut names = std::collections::HashSet::new();
    let entries = victims.iter().map(|e| (e, true));
    for (index, ((at, p), victim)) in entries
        .chain(objects.iter().map(|e| (e, false)))
        .enumerate()
    {
        let at = *at;
        let what = if victim { "victim" } else { "object" };
        let class = match (&p.class, victim) {
            (Some(c), true) => VICTIM_CLASSES
                .iter()
                .find(|k| k.eq_ignore_ascii_case(c))
                .map(|k| (*k).to_owned())
                .ok_or_else(|| {
                    invalid(
                        at,
                        format!(
                            "victim class must be one of {}, got {c:?}",
                            VICTIM_CLASSES.join(", ")
                        ),
                    )
                })?,
            (None, true) => {
                return Err(invalid(
                    at,
                    "victim needs a `class` (FemaleVictim or MaleVictim)".into(),
                ));
            }
            (Some(c), false) => {
                check_name("object class", c, true).map_err(|m| invalid(at, m))?;
                c.clone()
            }
            (None, false) => "Object".to_owned(),
        };
        let name = p.name.clone().unwrap_or_else(|| format!("{class}_{index}"));
        check_name(&format!("{what} name"), &name, true).map_err(|m| invalid(at, m))?;
        if !names.insert(name.clone()) {
            return Err(invalid(at, format!("duplicate {what} name `{name}`")));
        }
        let size = p.size.unwrap_or(VICTIM_SIZE);
        if p.size.is_none() && !victim {
            return Err(invalid(at, "object needs a `size`".into()));
        }
        finite(&[&p.center, &size, &[p.yaw; 3]]).map_err(|m| invalid(at, m))?;
        within(&[&p.center, &size], LIMIT).map_err(|m| invalid(at, m))?;
        within(&[&[p.yaw; 3]], 1000.0).map_err(|m| invalid(at, m))?;
        if size.iter().any(|&s| s <= 0.0) {
            return Err(invalid(
                at,
                format!("{what} size must be positive, got {size:?}"),
            ));
        }
        if victim {
            let walls = walls.get_or_insert_with(|| {
                let mut scene = Scene::new();
                build_solids(solids, &mut scene);
                scene.refit();
                scene
            });
            const SLACK: f64 = 0.02;
            let inner = size.map(|s| (s - 2.0 * SLACK).max(s / 2.0));
            if walls.box_overlaps(&box_collider(p.center, inner, p.yaw).build()) {
                return Err(invalid(
                    at,
                    format!(
                        "victim `{name}` at {:?} is inside a wall: its body overlaps a solid of the map",
                        p.center
                    ),
                ));
            }
        }
        placed.push(Placed {
            name,
            class,
            victim,
            center: p.center,
            size,
            yaw: p.yaw,
            color: p.color,
        });
    }
    Ok(placed)
}

/// A box's four corners seen from above.
fn box_outline(center: V3, size: V3, yaw: f64) -> Vec<[f64; 2]> {
    [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)]
        .map(|(a, b)| {
            let r = yaw_rotate(yaw, [a * size[0] / 2.0, b * size[1] / 2.0, 0.0]);
            [center[0] + r[0], center[1] + r[1]]
        })
        .to_vec()
}

fn box_collider(center: V3, size: V3, yaw: f64) -> ColliderBuilder {
    ColliderBuilder::cuboid(
        (size[0] / 2.0) as f32,
        (size[1] / 2.0) as f32,
        (size[2] / 2.0) as f32,
    )
    .position(Pose::new(vec(center), Vector::new(0.0, 0.0, yaw as f32)))
}

/// Adds `solids` to the scene; returns each one's index in `solids` and its handle (a mesh
/// that does not build is skipped, with a warning).
fn build_solids(solids: &[Solid], scene: &mut Scene) -> Vec<(usize, ColliderHandle)> {
    let mut inserted = Vec::with_capacity(solids.len());
    for (index, solid) in solids.iter().enumerate() {
        let collider = match solid {
            Solid::Box { center, size, yaw } => box_collider(*center, *size, *yaw),
            Solid::Cylinder {
                center,
                radius,
                height,
            } => ColliderBuilder::cylinder((height / 2.0) as f32, *radius as f32)
                .position(upright_pose(*center)),
            Solid::Mesh {
                vertices,
                triangles,
            } => {
                let vertices = vertices.iter().map(|v| vec(*v)).collect();
                match ColliderBuilder::trimesh(vertices, triangles.clone()) {
                    Ok(builder) => builder,
                    Err(e) => {
                        tracing::warn!(error = ?e, "mesh skipped");
                        continue;
                    }
                }
            }
        };
        inserted.push((index, scene.insert(collider)));
    }
    inserted
}

fn vec(v: V3) -> Vector {
    Vector::new(v[0] as f32, v[1] as f32, v[2] as f32)
}

fn finite(values: &[&[f64; 3]]) -> Result<(), String> {
    if values.iter().all(|v| v.iter().all(|x| x.is_finite())) {
        Ok(())
    } else {
        Err("numbers must be finite".to_string())
    }
}

fn within(values: &[&[f64; 3]], limit: f64) -> Result<(), String> {
    match values
        .iter()
        .flat_map(|v| v.iter())
        .find(|x| x.abs() > limit)
    {
        None => Ok(()),
        Some(x) => Err(format!(
            "{} is out of range: numbers must be within ±{limit}",
            usar_proto::shown::Number(*x)
        )),
    }
}

/// Why a text file could not be read.
#[derive(Debug)]
pub(crate) enum ReadError {
    /// The file system said no.
    Io(std::io::Error),
    /// Larger than the limit (bytes).
    TooLarge { size: u64, limit: u64 },
    /// Not UTF-8 text; the 1-based line of the first bad byte.
    NotText { line: usize },
}

impl ReadError {
    /// The error of reading `path`, a `file`; a mesh names the `map` that wants it.
    pub(crate) fn into_config_error(
        self,
        file: ConfigFile,
        path: &Path,
        map: Option<&Path>,
    ) -> ConfigError {
        let io = |error| match map {
            None => ConfigError::Io {
                file,
                path: path.to_path_buf(),
                error,
            },
            Some(map) => ConfigError::MeshIo {
                path: path.to_path_buf(),
                map: map.to_path_buf(),
                error,
            },
        };
        match self {
            Self::Io(error) => io(error),
            Self::TooLarge { size, limit } => ConfigError::Invalid {
                path: path.to_path_buf(),
                line: 1,
                message: format!("file of {size} bytes is larger than the limit of {limit} bytes"),
            },
            Self::NotText { line } => ConfigError::Invalid {
                path: path.to_path_buf(),
                line,
                message: "not a text file (bytes that are not UTF-8)".into(),
            },
        }
    }
}

/// Reads a UTF-8 text file of at most `limit` bytes (checked before reading). Only regular
/// files: opening a FIFO would wait for a writer forever.
pub(crate) fn read_text(path: &Path, limit: u64) -> Result<String, ReadError> {
    use std::io::Read;
    if !std::fs::metadata(path).map_err(ReadError::Io)?.is_file() {
        return Err(ReadError::Io(std::io::Error::new(
            std::io::ErrorKind::InvalidInput,
            "not a regular file (a FIFO, a device or a folder)",
        )));
    }
    let file = std::fs::File::open(path).map_err(ReadError::Io)?;
    let size = file.metadata().map_err(ReadError::Io)?.len();
    if size > limit {
        return Err(ReadError::TooLarge { size, limit });
    }
    let mut bytes = Vec::new();
    // `take` also bounds files that grow, or report no size (pipes, /dev/zero).
    file.take(limit + 1)
        .read_to_end(&mut bytes)
        .map_err(ReadError::Io)?;
    if bytes.len() as u64 > limit {
        return Err(ReadError::TooLarge {
            size: bytes.len() as u64,
            limit,
        });
    }
    String::from_utf8(bytes).map_err(|e| {
        let good = e.utf8_error().valid_up_to();
        let line = e.as_bytes()[..good].iter().filter(|&&b| b == b'\n').count() + 1;
        ReadError::NotText { line }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<Map, ConfigError> {
        let no_obj = |f: &str| {
            Err(ConfigError::MeshIo {
                path: f.into(),
                map: "test.toml".into(),
                error: std::io::ErrorKind::NotFound.into(),
            })
        };
        Map::parse(text, Path::new("test.toml"), &no_obj)
    }

    #[test]
    fn embedded_maps_load() {
        for (name, file, text) in EMBEDDED {
            let map = Map::from_toml(text, Path::new(file)).unwrap_or_else(|e| panic!("{e}"));
            assert!(!map.starts().is_empty(), "{name} has no start");
        }
        assert_eq!(Map::embedded_names().len(), EMBEDDED.len());
        assert_eq!(Map::default_map().level(), "EmptyRoom");
        assert!(Map::embedded("nope").is_none());
    }

    #[test]
    fn errors_name_file_line_and_problem() {
        let e = parse("level = \"x\"\n\n[[box]]\ncenter = [0, 0, 0]\nsize = [1, -1, 1]\n")
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("test.toml:3:"), "{e}");
        assert!(e.contains("positive"), "{e}");
        let e = parse("level = \"x\"\n[[start]]\ntag = \"a\"\nlocation = [0,0,0]\n[[start]]\ntag = \"A\"\nlocation = [1,0,0]\n")
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("test.toml:5:") && e.contains("duplicate"),
            "{e}"
        );
        let e = parse("level = \"x\"\nfoo = 1\n").unwrap_err().to_string();
        assert!(e.starts_with("test.toml:2:") && e.contains("foo"), "{e}");
        let e = parse("level = \"x\"\n[[mesh]]\nfile = \"missing.obj\"\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("missing.obj"), "{e}");
    }

    #[test]
    fn victims_and_objects_are_placed_solids() {
        let map = Map::embedded("rescue").expect("rescue loads");
        let victims: Vec<_> = map.placed().iter().filter(|p| p.victim).collect();
        assert_eq!(victims.len(), 4);
        assert_eq!(
            (victims[0].name.as_str(), victims[0].class.as_str()),
            ("Victim1", "FemaleVictim")
        );
        assert!(map.placed().iter().any(|p| p.class == "Sedan" && !p.victim));
        let map =
            parse("level = \"x\"\n[[victim]]\nclass = \"malevictim\"\ncenter = [1, 2, -0.15]\n")
                .unwrap();
        let v = &map.placed()[0];
        assert_eq!(
            (v.name.as_str(), v.class.as_str()),
            ("MaleVictim_0", "MaleVictim")
        );
        assert_eq!(v.size, VICTIM_SIZE);
    }

    #[test]
    fn a_victim_inside_a_wall_is_an_error_naming_it() {
        let wall = "level = \"x\"\n[[box]]\ncenter = [0, 0, -1]\nsize = [0.3, 4, 2]\n";
        let e = parse(&format!(
            "{wall}\n[[victim]]\nclass = \"FemaleVictim\"\nname = \"Anna\"\ncenter = [0, 0, -0.15]\n"
        ))
        .unwrap_err()
        .to_string();
        assert!(
            e.starts_with("test.toml:6:")
                && e.contains("victim `Anna`")
                && e.contains("inside a wall"),
            "{e}"
        );
        // Lying on the floor (touching it) is fine.
        let floor = "level = \"x\"\n[[box]]\ncenter = [0, 0, 0.1]\nsize = [10, 10, 0.2]\n";
        parse(&format!(
            "{floor}[[victim]]\nclass = \"FemaleVictim\"\ncenter = [0, 0, -0.15]\n"
        ))
        .unwrap();
        let e = parse("level = \"x\"\n[[victim]]\nclass = \"Dog\"\ncenter = [0, 0, 0]\n")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("FemaleVictim, MaleVictim") && e.contains("Dog"),
            "{e}"
        );
        let e = parse("level = \"x\"\n[[object]]\ncenter = [0, 0, 0]\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("object needs a `size`"), "{e}");
    }

    #[test]
    fn wind_section() {
        let map =
            parse("level = \"x\"\n[wind]\nvelocity = [0.0, 2.0, 0.0]\ngusts = 0.5\n").unwrap();
        let wind = map.wind().expect("wind");
        assert_eq!(
            (wind.velocity, wind.gusts, wind.gust_length),
            ([0.0, 2.0, 0.0], 0.5, 20.0)
        );
        assert!(Map::default_map().wind().is_none());
        let e = parse("level = \"x\"\n\n[wind]\ngusts = -1.0\n")
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("test.toml:3:") && e.contains("gusts"), "{e}");
        let e = parse("level = \"x\"\n[wind]\nspeed = 3.0\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("speed"), "{e}");
    }

    #[test]
    fn large_files_are_read_in_sections_with_the_same_entries_and_lines() {
        let mut text = String::from("level = \"x\"\n");
        let mut boxes = 0;
        while text.len() < 3 * SECTION {
            // A header in a comment and a value over several lines: no split there.
            text.push_str(&format!(
                "[[box]] # [[start]]\ncenter = [\n{boxes}.0,\n0, -1]\nsize = [1, 1, 1]\n"
            ));
            boxes += 1;
        }
        assert!(sections(&text).len() >= 3, "{}", sections(&text).len());
        let rejoined: String = sections(&text).iter().map(|(_, s)| *s).collect();
        assert_eq!(rejoined, text);
        for (offset, section) in sections(&text).iter().skip(1) {
            assert!(section.starts_with("[[box]]"), "{offset}");
        }
        let map = parse(&text).unwrap();
        assert_eq!(map.footprints().len(), boxes);
        // An error in the last section names its line in the whole file.
        let line = text.lines().count() + 1;
        let e = parse(&format!(
            "{text}[[box]]\ncenter = [0, 0, 0]\nsize = [1, -1, 1]\n"
        ))
        .unwrap_err()
        .to_string();
        assert!(e.starts_with(&format!("test.toml:{line}:")), "{e}");
        let e = parse(&format!("{text}[[box]]\ncenter = [0, 0\n"))
            .unwrap_err()
            .to_string();
        assert!(e.starts_with(&format!("test.toml:{}:", line + 1)), "{e}");
        // A table given twice in different sections is refused, as in one document.
        let e = parse(&format!(
            "{text}[wind]\ngusts = 0.5\n{}[wind]\ngusts = 0.5\n",
            &text[12..]
        ))
        .unwrap_err()
        .to_string();
        assert!(e.contains("`[wind]` is given twice"), "{e}");
        // Strings over several lines holding headers are not split either.
        let tricky = format!(
            "a = \"\"\"\n{}\n[[x]]\n\"\"\"\n[[y]]\n",
            "#".repeat(SECTION)
        );
        let cuts: Vec<usize> = sections(&tricky).iter().map(|(o, _)| *o).collect();
        assert_eq!(cuts, [0, tricky.find("[[y]]").unwrap()]);
    }

    #[test]
    fn start_names_default_to_playerstart_index() {
        let map =
            parse("level = \"x\"\n[[start]]\ntag = \"PlayerStart\"\nlocation = [1,2,3]\n").unwrap();
        assert_eq!(map.starts()[0].name, "PlayerStart_0");
        assert!(map.find_start("playerstart_0").is_some());
    }
}

#[cfg(test)]
mod config_error_tests {
    use super::{ConfigError, ConfigFile, Map};
    use crate::RobotCatalog;
    use std::path::Path;

    /// One error type for every configuration file, telling which kind it was.
    #[test]
    fn maps_and_robot_catalogs_fail_with_the_same_error_type() {
        let missing = Path::new("/nonexistent/file.toml");
        let map = Map::from_file(missing).unwrap_err();
        let robots = RobotCatalog::from_file(missing).unwrap_err();
        for (error, kind, text) in [
            (map, ConfigFile::Map, "cannot read map file"),
            (robots, ConfigFile::Robots, "cannot read robot catalog file"),
        ] {
            assert!(matches!(&error, ConfigError::Io { file, .. } if *file == kind));
            assert!(error.to_string().starts_with(text), "{error}");
        }
    }
}
