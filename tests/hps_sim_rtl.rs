//! hps-sim with the Verilated RTL behind hal-avalon's driver: frames over
//! real TCP equal the model's, in frame mode (the RTL's AXI master writing
//! the ring) and in row mode.
#![cfg(rtl_verilated)]

use std::io::{Read, Write};
use std::net::TcpStream;
use std::time::Duration;

use hps_sim::{Config, Device, HpsSim, RenderMode};
use model::{render_frame, Light};
use rt_services::encode_request;

fn rtl_sim(render: RenderMode) -> HpsSim {
    let config = Config { render, device: Device::Rtl, ..Config::default() };
    HpsSim::start_config("127.0.0.1:0".parse().expect("address"), config, false).expect("hps-sim with the RTL starts")
}

/// One frame over the seed protocol, as `rt-client frame` fetches it.
fn fetch(sim: &HpsSim, l: &Light) -> Vec<u8> {
    let mut s = TcpStream::connect(sim.frame_addr()).expect("connect");
    s.set_read_timeout(Some(Duration::from_secs(120))).expect("timeout");
    s.write_all(&encode_request(l)).expect("request");
    let mut frame = Vec::new();
    s.read_to_end(&mut frame).expect("the frame, then the server closes");
    frame
}

#[test]
fn frame_mode_on_the_rtl_serves_the_models_frames() {
    let sim = rtl_sim(RenderMode::Frames);
    for (x, y, z) in [(3.0, 4.0, -2.0), (-4.0, 6.0, -3.0), (0.5, 0.2, -1.0)] {
        let l = Light::from_world(x, y, z).expect("in range");
        assert!(fetch(&sim, &l) == render_frame(&l), "light {x},{y},{z}: frame differs from the model");
    }
}

#[test]
fn row_mode_on_the_rtl_serves_the_models_frame() {
    let sim = rtl_sim(RenderMode::Rows);
    let l = Light::from_world(2.0, 1.0, -2.5).expect("in range");
    assert!(fetch(&sim, &l) == render_frame(&l), "frame differs from the model");
}
