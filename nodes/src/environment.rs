//! The plant as the environment of the scripted nodes.

use crate::plant::{Plant, PlantConfig};
use crate::script::{Environment, Port, Signals};
use bus::time::BusTime;

impl Environment for Plant {
    fn advance_to(&mut self, t: BusTime) {
        Plant::advance_to(self, t);
    }
    fn port(&self, name: &str) -> Option<Port> {
        Plant::port(name)
    }
    fn read(&self, port: Port) -> Option<f64> {
        self.read_port(port)
    }
    fn write(&mut self, port: Port, value: f64) -> bool {
        self.write_port(port, value)
    }
    fn next_change(&self, t: BusTime) -> BusTime {
        Plant::next_step(self, t)
    }
}

/// The plant's signal names, for validating scripts.
pub struct PlantSignals;

impl Signals for PlantSignals {
    fn is_signal(&self, name: &str) -> bool {
        Plant::is_signal(name)
    }
    fn is_input(&self, name: &str) -> bool {
        Plant::is_input(name)
    }
}

/// Problems with a plant config, as (field, message).
pub fn validate_plant(config: &PlantConfig) -> Vec<(String, String)> {
    crate::plant::validate(config)
}
