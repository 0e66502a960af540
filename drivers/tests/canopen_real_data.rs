//! The CANopen readers and codecs against real device descriptions and real bus traces.

use canopen_rs::nmt::{NmtCommand, NmtState};
use canopen_rs::sdo::decode_upload_expedited_response;
use canopen_rs::DataType;
use videt_drive_description::Eds;
use videt_drivers::canopen::trace::{decode, parse_candump, Message};
use videt_drivers::cia402::compat::{missing_objects, missing_objects_with};
use videt_drivers::cia402::pdo::Status;
use videt_drivers::cia402::AnalogInputObject;
use videt_drivers::cia402::PowerState;

fn read(rel: &str) -> Option<String> {
    let p = videt_testdata::data_dir(rel)?;
    Some(std::fs::read_to_string(p).expect("readable data file"))
}

fn eds(name: &str) -> Option<Eds> {
    read(&format!("canopen/eds/{name}")).map(|t| Eds::parse(&t).expect(name))
}

#[test]
fn every_real_eds_and_dcf_parses() {
    let Some(dir) = videt_testdata::data_dir("canopen/eds") else {
        return;
    };
    let mut n = 0;
    for entry in std::fs::read_dir(dir).unwrap() {
        let p = entry.unwrap().path();
        let ext = p.extension().and_then(|e| e.to_str()).unwrap_or("");
        if ext != "eds" && ext != "dcf" {
            continue;
        }
        let text = std::fs::read_to_string(&p).unwrap();
        let eds = Eds::parse(&text).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
        assert!(
            eds.entry(0x1000, 0).is_some(),
            "{}: no device type",
            p.display()
        );
        assert!(eds.entries().count() > 50, "{}", p.display());
        n += 1;
    }
    assert_eq!(n, 9);
}

#[test]
fn node_id_expressions_and_dcf_values_resolve() {
    let Some(epos) = eds("epos4_50_15_can_ec90flat_gp52c_mile800_node1.dcf") else {
        return;
    };
    // CRLF file; TPDO1 COB-ID defaults to $NODEID+0x180-style values.
    let cob = epos.value(0x1800, 1, 1).unwrap().unwrap();
    assert_eq!(cob & 0x7FF, 0x181);
    // A DCF carries the configured value: the motor rated torque of this drive.
    assert_eq!(epos.value(0x6076, 0, 1).unwrap(), Some(512_871));
    assert_eq!(epos.entry(0x6076, 0).unwrap().data_type, Some(7));
    let Some(faulhaber) = eds("605.3150.67-A-EK-2-60.eds") else {
        return;
    };
    assert_eq!(faulhaber.value(0x1400, 1, 5).unwrap(), Some(0x205));
}

#[test]
fn the_epos4_has_every_object_of_the_driver_and_the_faulhaber_mcbl_lacks_torque_mode() {
    let Some(epos) = eds("epos4_50_15_can_ec90flat_gp52c_mile800_node1.dcf") else {
        return;
    };
    assert_eq!(missing_objects(&epos), vec![]);
    let Some(mcbl) = eds("605.3150.67-A-EK-2-60.eds") else {
        return;
    };
    let missing: Vec<u16> = missing_objects(&mcbl).iter().map(|m| m.index).collect();
    // The MCBL 300x CO predates cyclic synchronous torque mode: no target torque, no 0x603F.
    assert!(missing.contains(&0x6071), "{missing:x?}");
    assert!(missing.contains(&0x603F), "{missing:x?}");
}

#[test]
fn the_epos4_maps_its_analog_input_voltage_but_has_no_cia401_input() {
    let Some(epos) = eds("epos4_50_15_can_ec90flat_gp52c_mile800_node1.dcf") else {
        return;
    };
    let epos_input = AnalogInputObject {
        index: 0x3160,
        subindex: 1,
    };
    assert_eq!(missing_objects_with(&epos, Some(epos_input)), vec![]);
    let missing = missing_objects_with(&epos, Some(AnalogInputObject::default()));
    assert_eq!(missing.len(), 1, "{missing:?}");
    assert_eq!(
        (missing[0].index, missing[0].subindex, missing[0].problem),
        (0x6401, 1, "absent")
    );
}

#[test]
fn the_simulated_drive_dictionary_matches_a_real_drive() {
    let Some(epos) = eds("epos4_50_15_can_ec90flat_gp52c_mile800_node1.dcf") else {
        return;
    };
    use std::sync::Arc;
    use videt_sim::cia402_node::{NodeFaults, SimDriveNode, SimDriveSpec};
    let node = SimDriveNode::new(
        SimDriveSpec {
            node_id: 1,
            axis: 0,
            rated_torque_mnm: 100,
            boot_delay: std::time::Duration::ZERO,
        },
        Arc::new(NodeFaults::default()),
    );
    let mut checked = 0;
    for (index, sub) in node.object_addresses() {
        let value = node.read_object(index, sub).unwrap();
        let Some(real) = epos.entry(index, sub) else {
            // Objects a real EPOS4 lacks are allowed only for the optional torque limit, the
            // optional polarity (an EPOS4 keeps its directions in its own axis configuration)
            // and the CiA 401 analog input (the EPOS4 has its analog inputs at 0x3160).
            assert!(
                index == 0x6072 || index == 0x607E || index == 0x6401,
                "{index:#06x}:{sub} not in the EPOS4 dictionary"
            );
            continue;
        };
        assert_eq!(
            real.data_type,
            Some(value.data_type() as u16),
            "{index:#06x}:{sub} data type"
        );
        checked += 1;
    }
    assert!(checked > 40, "{checked}");
}

#[test]
fn decodes_a_boot_and_sdo_configuration_trace() {
    let Some(t) = read("canopen/traces/ros2_canopen_issue298_paltech_node1_boot_sdo_config.txt")
    else {
        return;
    };
    let frames = parse_candump(&t).unwrap();
    let msgs: Vec<Message> = frames.iter().map(|f| decode(f.cob_id, &f.data)).collect();
    assert_eq!(msgs[0], Message::BootUp(1));
    assert_eq!(msgs[1], Message::Heartbeat(1, NmtState::PreOperational));
    assert!(msgs.contains(&Message::BootUp(2)));
    assert!(msgs.contains(&Message::Nmt {
        command: NmtCommand::ResetCommunication,
        target: 0
    }));
    assert!(msgs.contains(&Message::Sync(None)));
    // The device type read: 0x00020192 = CiA 402 drive.
    let reply = msgs
        .iter()
        .find_map(|m| match m {
            Message::SdoResponse(1, p) if p[1] == 0x00 && p[2] == 0x10 => Some(*p),
            _ => None,
        })
        .unwrap();
    let (addr, value) = decode_upload_expedited_response(&reply, DataType::Unsigned32).unwrap();
    assert_eq!(addr.index, 0x1000);
    assert_eq!(value, canopen_rs::Value::Unsigned32(0x0002_0192));
    // The heartbeat producer time write: 1000 ms to 0x1017, acknowledged.
    assert!(msgs.contains(&Message::SdoRequest(
        1,
        [0x2B, 0x17, 0x10, 0x00, 0xE8, 0x03, 0, 0]
    )));
    assert!(msgs.contains(&Message::SdoResponse(
        1,
        [0x60, 0x17, 0x10, 0x00, 0, 0, 0, 0]
    )));
}

#[test]
fn decodes_a_trace_of_nmt_start_and_process_data() {
    let Some(t) = read("canopen/traces/ros2_canopen_issue356_nanotec_N5_node1_boot_pdo.txt") else {
        return;
    };
    let frames = parse_candump(&t).unwrap();
    let msgs: Vec<Message> = frames.iter().map(|f| decode(f.cob_id, &f.data)).collect();
    assert!(msgs.contains(&Message::Nmt {
        command: NmtCommand::StartRemoteNode,
        target: 1
    }));
    assert!(msgs.contains(&Message::Heartbeat(1, NmtState::Operational)));
    let tpdos = msgs
        .iter()
        .filter(|m| matches!(m, Message::Tpdo(_, 1, _)))
        .count();
    assert_eq!(tpdos, 4);
    // TPDO1 of this drive starts with its statusword: 0x0640 = switch on disabled.
    let Message::Tpdo(0, 1, data) = &msgs[msgs.len() - 6] else {
        panic!("{:?}", msgs[msgs.len() - 6]);
    };
    let sw = u16::from_le_bytes([data[0], data[1]]);
    assert_eq!(
        PowerState::from_statusword(sw),
        PowerState::SwitchOnDisabled
    );
    assert!(matches!(msgs.last(), Some(Message::Rpdo(0, 1, d)) if d.len() == 7));
}

#[test]
fn decodes_a_drive_booting_into_fault() {
    let Some(t) = read("canopen/traces/ros_canopen_issue259_timple_node3_fault_boot.txt") else {
        return;
    };
    let frames = parse_candump(&t).unwrap();
    assert!(frames.iter().all(|f| f.time_s.is_some()));
    let msgs: Vec<Message> = frames.iter().map(|f| decode(f.cob_id, &f.data)).collect();
    assert_eq!(msgs[1], Message::BootUp(3));
    let Message::Emcy(3, emcy) = &msgs[2] else {
        panic!("{:?}", msgs[2]);
    };
    assert_eq!(emcy.error_code, 0x81B0);
    assert!(
        videt_drivers::canopen::codes::emcy_description(emcy.error_code).contains("communication")
    );
    // The statusword read answers 0x0218: the drive is in fault.
    let sw_reply = msgs
        .iter()
        .find_map(|m| match m {
            Message::SdoResponse(3, p) if p[1] == 0x41 && p[2] == 0x60 => Some(*p),
            _ => None,
        })
        .unwrap();
    let (_, v) = decode_upload_expedited_response(&sw_reply, DataType::Unsigned16).unwrap();
    let canopen_rs::Value::Unsigned16(sw) = v else {
        panic!("{v:?}")
    };
    assert_eq!(sw, 0x0218);
    assert_eq!(PowerState::from_statusword(sw), PowerState::Fault);
    let status = Status {
        statusword: sw,
        error_code: emcy.error_code,
    };
    assert_eq!(Status::decode(&status.encode()), Some(status));
}
