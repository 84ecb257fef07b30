//! The integration tests, in one binary: each file is a module, and all of
//! them share `common`. One binary links `vl` once, where thirty linked it
//! thirty times. The tests that time the lab under load run in `alone`.

mod common;

mod accounts;
mod admission;
mod camera_cli;
mod camera_follow;
mod camera_map;
mod camera_replay;
mod cameras;
mod class;
mod cli;
mod controllers;
mod docs_drift;
mod experiment_media;
mod experiments;
mod faults;
mod following_in_sim;
mod forecast;
mod foxglove;
mod foxglove_outside;
mod fuzz;
mod gamepad;
mod guest_window;
mod host_socket;
mod khepera_emu;
mod lab_check;
mod lab_nets;
mod lab_ready;
mod lti;
mod media;
mod numbers;
mod petri_cli;
mod petri_corpus;
mod petri_props;
mod plan_cli;
mod planning_props;
mod protocol_docs;
mod protocol_props;
mod readme;
mod reconnect;
mod recording_damage;
mod recording_room;
mod recordings;
mod safety;
mod serial_safety;
mod sim_cli;
mod sim_link;
mod structure;
mod tls;
mod vision;
mod web;
