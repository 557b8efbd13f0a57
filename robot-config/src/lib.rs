//! # robot-config: a robot's whole-body configuration as a TOML file
//!
//! Reads a robot's `config.toml` (Justin's: `fixtures/robots/justin/config.toml`): gains,
//! limits, the hierarchies as levels of named tasks, the service-task parameterisations and
//! the platform's parameters. [`parse`] refuses a bad file with a one-line [`ConfigError`],
//! `<file>:<line>: <key>: <problem>`: a missing or unknown key, a negative or non-finite
//! stiffness, damping or limit, a task or hand of a part the robot does not have (its parts are
//! the file's `[robot]` table: the arms by name and their joint count, a torso, a platform), a
//! value of a part it does not have or a part's value left out, an `arm` list of another length
//! than `[robot] arm_joints`, a hierarchy with more levels or tasks
//! than the kernel holds, a task twice. [`rust_constants`] turns a valid configuration into
//! Rust constants, one module per TOML table, which the `no_std` fixtures compile in through
//! their build script: the board needs neither `std` nor a parser.

mod codegen;
pub mod collision;
mod error;
pub mod schema;
pub mod values;

pub use codegen::rust_constants;
pub use error::ConfigError;
pub use schema::RobotConfig;

/// Parses and validates the configuration `text`; `origin` names the file in errors. The
/// `[robot]` table is read first: the task and hand names of the rest are checked against it.
pub fn parse(text: &str, origin: &str) -> Result<RobotConfig, ConfigError> {
    let head: RobotHead = read(text, origin)?;
    let config: RobotConfig = head.robot.reading(|| read(text, origin))?;
    match config.missing_part() {
        Some((key, problem)) => Err(ConfigError::new(origin, text, None, &key, &problem)),
        None => Ok(config),
    }
}

/// The `[robot]` table of a file, the other tables left for [`parse`].
#[derive(serde::Deserialize)]
struct RobotHead {
    robot: values::Robot,
}

/// `text` deserialized as `C`, or the one-line error.
fn read<C: serde::de::DeserializeOwned>(text: &str, origin: &str) -> Result<C, ConfigError> {
    let deserializer = toml::Deserializer::parse(text)
        .map_err(|error| ConfigError::new(origin, text, error.span().map(|s| s.start), "", error.message()))?;
    serde_path_to_error::deserialize(deserializer).map_err(|error| {
        let key = error.path().to_string();
        let inner = error.into_inner();
        ConfigError::new(origin, text, inner.span().map(|s| s.start), &key, inner.message())
    })
}

/// Reads and parses the file at `path`.
pub fn load(path: &std::path::Path) -> Result<RobotConfig, ConfigError> {
    let origin = path.display().to_string();
    let text =
        std::fs::read_to_string(path).map_err(|error| ConfigError::new(&origin, "", None, "", &error.to_string()))?;
    parse(&text, &origin)
}
