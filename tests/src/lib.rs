//! Cross-crate integration tests: the thesis' results as executable checks, one module per
//! subject (dynamics against independent references and properties, simulation, fixtures).
//! The tests live in `#[cfg(test)]` modules; the library holds only the oracles that other
//! test harnesses share ([`contract`]).

pub mod contract;

#[cfg(test)]
mod collision;
#[cfg(test)]
mod dynamics;
#[cfg(test)]
mod dynamics_properties;
#[cfg(test)]
mod dynamics_reference;
#[cfg(test)]
mod fixed_base;
#[cfg(test)]
mod fixtures_models;
#[cfg(test)]
mod hierarchy;
#[cfg(test)]
mod imported_robots;
#[cfg(test)]
mod manipulability;
#[cfg(test)]
mod multilevel;
#[cfg(test)]
mod platform;
#[cfg(test)]
mod robustness;
#[cfg(test)]
mod simulation;
#[cfg(test)]
mod support;
#[cfg(test)]
mod three_arms;
#[cfg(test)]
mod torso_workspace;
#[cfg(test)]
mod tree_factor;
