//! The computer's part of the commissioning check: a PREEMPT_RT kernel, the control CPU
//! isolated and allowed to the service, the memory-lock and real-time priority limits the
//! service gets, and the CAN interface up at `drives.bitrate` without bus errors.
//!
//! The service's limits and CPUs are those systemd gives its unit (`systemctl show videtd`,
//! drop-ins included) when the unit is installed; otherwise this process's own.

use std::process::Command;

use videt_config::Config;
use videt_service::init::commission::StepReport;

/// What the facts of the machine are read from (the live system, or a test's files).
pub trait Machine {
    /// A file's text (`/sys/...`, `/proc/...`), if readable.
    fn read(&self, path: &str) -> Option<String>;
    /// The output of `systemctl show videtd -p ...`, when systemd knows the unit.
    fn service_properties(&self) -> Option<String>;
    /// The JSON `ip -details -statistics -json link show dev IF` prints, if the interface
    /// exists.
    fn can_link(&self, interface: &str) -> Option<String>;
    /// Whether this process runs as root.
    fn is_root(&self) -> bool;
}

/// This computer.
pub struct ThisComputer;

impl Machine for ThisComputer {
    fn read(&self, path: &str) -> Option<String> {
        std::fs::read_to_string(path).ok()
    }
    fn service_properties(&self) -> Option<String> {
        let out = Command::new("systemctl")
            .args([
                "show",
                "videtd",
                "-p",
                "LoadState",
                "-p",
                "CPUAffinity",
                "-p",
                "LimitMEMLOCK",
                "-p",
                "LimitRTPRIO",
            ])
            .output()
            .ok()?;
        let text = String::from_utf8_lossy(&out.stdout).into_owned();
        (out.status.success() && text.contains("LoadState=loaded")).then_some(text)
    }
    fn can_link(&self, interface: &str) -> Option<String> {
        let out = Command::new("ip")
            .args([
                "-details",
                "-statistics",
                "-json",
                "link",
                "show",
                "dev",
                interface,
            ])
            .output()
            .ok()?;
        out.status
            .success()
            .then(|| String::from_utf8_lossy(&out.stdout).into_owned())
    }
    fn is_root(&self) -> bool {
        // SAFETY: geteuid has no preconditions and cannot fail.
        unsafe { libc::geteuid() == 0 }
    }
}

/// The computer's steps.
pub fn check(config: &Config, m: &dyn Machine) -> Vec<StepReport> {
    let unit = m.service_properties();
    let property = |name: &str| {
        unit.as_deref().and_then(|u| {
            u.lines()
                .find_map(|l| l.strip_prefix(name)?.strip_prefix('='))
                .map(str::to_string)
        })
    };
    vec![
        preempt_rt(m),
        control_cpu(config, m, property("CPUAffinity")),
        memlock(config, m, property("LimitMEMLOCK")),
        rt_priority(config, m, property("LimitRTPRIO")),
        can_interface(config, m),
    ]
}

fn preempt_rt(m: &dyn Machine) -> StepReport {
    let name = "computer.preempt-rt";
    let realtime = m
        .read("/sys/kernel/realtime")
        .is_some_and(|t| t.trim() == "1");
    let version = m.read("/proc/sys/kernel/version").unwrap_or_default();
    let version = version.trim();
    if realtime || version.contains("PREEMPT_RT") {
        StepReport::pass(name, format!("a PREEMPT_RT kernel ({version})"))
    } else {
        StepReport::fail(name, format!("not a PREEMPT_RT kernel ({version})"), Vec::new())
            .with_wiring("install and boot a PREEMPT_RT kernel (Debian: linux-image-rt-amd64 or linux-image-rt-arm64)")
    }
}

/// The CPUs of a list such as `1-3,5`.
pub fn cpu_list(text: &str) -> Vec<u32> {
    let mut cpus = Vec::new();
    for part in text
        .trim()
        .split(',')
        .map(str::trim)
        .filter(|p| !p.is_empty())
    {
        let (a, b) = part.split_once('-').unwrap_or((part, part));
        if let (Ok(a), Ok(b)) = (a.trim().parse::<u32>(), b.trim().parse::<u32>()) {
            cpus.extend(a..=b.min(a + 4096));
        }
    }
    cpus
}

fn control_cpu(config: &Config, m: &dyn Machine, unit_affinity: Option<String>) -> StepReport {
    let name = "computer.control-cpu";
    let Ok(cpu) = u32::try_from(config.realtime.control_cpu) else {
        return StepReport::skipped(
            name,
            "realtime.control_cpu = -1: the control thread is not pinned",
        );
    };
    let online = cpu_list(&m.read("/sys/devices/system/cpu/online").unwrap_or_default());
    let isolated = cpu_list(
        &m.read("/sys/devices/system/cpu/isolated")
            .unwrap_or_default(),
    );
    let (allowed_by, allowed) = match unit_affinity.filter(|a| !a.trim().is_empty()) {
        Some(a) => (
            "videtd's unit (CPUAffinity)",
            cpu_list(&a.replace(' ', ",")),
        ),
        None => {
            let status = m.read("/proc/self/status").unwrap_or_default();
            let list = status
                .lines()
                .find_map(|l| l.strip_prefix("Cpus_allowed_list:"))
                .unwrap_or("");
            ("this process", cpu_list(list))
        }
    };
    let measured = format!(
        "CPU {cpu}: online {online:?}, isolated {isolated:?}, allowed to {allowed_by} {allowed:?}"
    );
    if !online.contains(&cpu) {
        let fix = isolated
            .iter()
            .chain(&online)
            .find(|c| **c != 0 && allowed.contains(c))
            .map(|c| {
                videt_config::edit::Fix::new(
                    "realtime.control_cpu",
                    None,
                    videt_config::edit::FixValue::Integer(i64::from(*c)),
                )
            });
        return StepReport::fail(
            name,
            format!("{measured}: the CPU is not online"),
            fix.into_iter().collect(),
        );
    }
    if !allowed.contains(&cpu) {
        return StepReport::fail(name, format!("{measured}: the service may not run on it"), Vec::new())
            .with_wiring(format!("allow CPU {cpu} to videtd: `systemctl edit videtd`, [Service] CPUAffinity= a list that holds {cpu}"));
    }
    if !isolated.contains(&cpu) {
        return StepReport::fail(name, format!("{measured}: other tasks may run on it"), Vec::new())
            .with_wiring(format!("isolate CPU {cpu}: add isolcpus={cpu} nohz_full={cpu} rcu_nocbs={cpu} to the kernel's command line"));
    }
    StepReport::pass(name, measured)
}

/// `Max locked memory` / `Max realtime priority` of this process's limits (soft), `None` for
/// unlimited.
fn own_limit(m: &dyn Machine, which: &str) -> Option<Option<u64>> {
    let limits = m.read("/proc/self/limits")?;
    let line = limits.lines().find(|l| l.starts_with(which))?;
    let soft = line[which.len()..].split_whitespace().next()?;
    Some(if soft == "unlimited" {
        None
    } else {
        Some(soft.parse().ok()?)
    })
}

fn memlock(config: &Config, m: &dyn Machine, unit: Option<String>) -> StepReport {
    let name = "computer.memlock";
    if !config.realtime.lock_memory {
        return StepReport::skipped(name, "realtime.lock_memory = false: memory is not locked");
    }
    // systemd prints infinity as the largest u64.
    if let Some(u) = unit {
        return match u.trim().parse::<u64>() {
            Ok(v) if v == u64::MAX => {
                StepReport::pass(name, "videtd's unit: LimitMEMLOCK=infinity")
            }
            _ if u.trim() == "infinity" => {
                StepReport::pass(name, "videtd's unit: LimitMEMLOCK=infinity")
            }
            _ => StepReport::fail(
                name,
                format!("videtd's unit: LimitMEMLOCK={}", u.trim()),
                Vec::new(),
            )
            .with_wiring("set LimitMEMLOCK=infinity for videtd (`systemctl edit videtd`)"),
        };
    }
    match own_limit(m, "Max locked memory") {
        Some(None) => StepReport::pass(name, "this process may lock unlimited memory"),
        _ if m.is_root() => StepReport::pass(
            name,
            "this process runs as root (CAP_IPC_LOCK: not bound by the memory-lock limit)",
        ),
        Some(Some(bytes)) => StepReport::fail(
            name,
            format!("this process may lock {} KiB of memory", bytes / 1024),
            Vec::new(),
        )
        .with_wiring("run videtd from its unit (LimitMEMLOCK=infinity), or raise memlock in /etc/security/limits.d"),
        None => StepReport::skipped(name, "the memory-lock limit could not be read"),
    }
}

fn rt_priority(config: &Config, m: &dyn Machine, unit: Option<String>) -> StepReport {
    let name = "computer.realtime-priority";
    let wanted = u64::from(config.realtime.control_priority);
    let rt_runtime = m
        .read("/proc/sys/kernel/sched_rt_runtime_us")
        .map(|t| t.trim().to_string())
        .unwrap_or_default();
    let (who, limit) = match unit {
        Some(u) => ("videtd's unit (LimitRTPRIO)", u.trim().parse::<u64>().ok()),
        None if m.is_root() => ("this process (root)", Some(99)),
        None => (
            "this process",
            own_limit(m, "Max realtime priority").map(|l| l.unwrap_or(99)),
        ),
    };
    let measured = format!(
        "{who}: priority up to {}, realtime.control_priority = {wanted}; sched_rt_runtime_us = {rt_runtime}",
        limit.map_or("unknown".into(), |l| l.to_string())
    );
    match limit {
        Some(l) if l >= wanted => StepReport::pass(name, measured),
        Some(_) => StepReport::fail(name, measured, Vec::new()).with_wiring(format!(
            "raise videtd's LimitRTPRIO to at least {wanted} (`systemctl edit videtd`)"
        )),
        None => StepReport::skipped(name, measured),
    }
}

fn can_interface(config: &Config, m: &dyn Machine) -> StepReport {
    let name = "computer.can";
    let d = &config.drives;
    let interface = &d.can_interface;
    let up_command = format!(
        "ip link set {interface} type can bitrate {} && ip link set {interface} up",
        d.bitrate
    );
    let Some(json) = m.can_link(interface) else {
        return StepReport::fail(
            name,
            format!("no network interface {interface} (drives.can_interface)"),
            Vec::new(),
        )
        .with_wiring(format!("connect the CAN adapter, or name its interface in drives.can_interface; then {up_command}"));
    };
    let link: serde_json::Value = serde_json::from_str(&json).unwrap_or_default();
    let link = link.get(0).cloned().unwrap_or_default();
    let kind = link
        .pointer("/linkinfo/info_kind")
        .and_then(|k| k.as_str())
        .unwrap_or("");
    let up = link
        .get("flags")
        .and_then(|f| f.as_array())
        .is_some_and(|f| f.iter().any(|x| x == "UP"));
    if kind != "can" && kind != "vcan" {
        return StepReport::fail(
            name,
            format!("{interface} is not a CAN interface (kind {kind:?})"),
            Vec::new(),
        )
        .with_wiring("name the CAN adapter's interface in drives.can_interface");
    }
    if !up {
        return StepReport::fail(name, format!("{interface} is down"), Vec::new())
            .with_wiring(up_command);
    }
    if kind == "vcan" {
        return StepReport::pass(
            name,
            format!("{interface} is up (a virtual CAN interface: no bit rate or bus errors)"),
        );
    }
    let data = link
        .pointer("/linkinfo/info_data")
        .cloned()
        .unwrap_or_default();
    let bitrate = data.pointer("/bittiming/bitrate").and_then(|b| b.as_u64());
    let state = data
        .get("state")
        .and_then(|s| s.as_str())
        .unwrap_or("unknown");
    let counter = |which: &str| {
        data.pointer(&format!("/berr_counter/{which}"))
            .and_then(|c| c.as_u64())
            .unwrap_or(0)
    };
    let (tx, rx) = (counter("tx"), counter("rx"));
    let measured = format!(
        "{interface} is up at {} bit/s, state {state}, error counters tx {tx} rx {rx}",
        bitrate.map_or("an unknown rate".into(), |b| b.to_string())
    );
    if bitrate != Some(u64::from(d.bitrate)) {
        return StepReport::fail(
            name,
            format!("{measured}; drives.bitrate = {}", d.bitrate),
            Vec::new(),
        )
        .with_wiring(format!(
            "ip link set {interface} down && {up_command} (or set drives.bitrate to the drives' rate)"
        ));
    }
    if state != "ERROR-ACTIVE" || tx > 0 || rx > 0 {
        return StepReport::fail(name, measured, Vec::new()).with_wiring(
            "bus errors: check the termination (120 Ω at both ends of the bus), the cable and the drives' bit rate",
        );
    }
    StepReport::pass(name, measured)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::HashMap;
    use videt_service::init::commission::Verdict;

    #[derive(Default)]
    struct Fake {
        files: HashMap<&'static str, String>,
        unit: Option<String>,
        link: Option<String>,
        root: bool,
    }

    impl Machine for Fake {
        fn read(&self, path: &str) -> Option<String> {
            self.files.get(path).cloned()
        }
        fn service_properties(&self) -> Option<String> {
            self.unit.clone()
        }
        fn can_link(&self, _: &str) -> Option<String> {
            self.link.clone()
        }
        fn is_root(&self) -> bool {
            self.root
        }
    }

    fn verdicts(steps: &[StepReport]) -> Vec<(String, Verdict)> {
        steps.iter().map(|s| (s.name.clone(), s.verdict)).collect()
    }

    fn rt_machine() -> Fake {
        let mut f = Fake::default();
        f.files.insert("/sys/kernel/realtime", "1\n".into());
        f.files.insert(
            "/proc/sys/kernel/version",
            "#1 SMP PREEMPT_RT Debian\n".into(),
        );
        f.files
            .insert("/sys/devices/system/cpu/online", "0-3\n".into());
        f.files
            .insert("/sys/devices/system/cpu/isolated", "1\n".into());
        f.files
            .insert("/proc/sys/kernel/sched_rt_runtime_us", "950000\n".into());
        f.unit = Some(
            "LoadState=loaded\nCPUAffinity=1 2 3\nLimitMEMLOCK=18446744073709551615\nLimitRTPRIO=90\n"
                .into(),
        );
        f.link = Some(
            r#"[{"ifname":"can0","flags":["NOARP","UP","LOWER_UP"],"linkinfo":{"info_kind":"can","info_data":{"state":"ERROR-ACTIVE","berr_counter":{"tx":0,"rx":0},"bittiming":{"bitrate":1000000}}}}]"#
                .into(),
        );
        f
    }

    #[test]
    fn a_computer_set_up_for_the_service_passes_every_step() {
        let steps = check(&Config::default(), &rt_machine());
        assert!(
            steps.iter().all(|s| s.verdict == Verdict::Pass),
            "{steps:#?}"
        );
    }

    #[test]
    fn each_missing_piece_fails_its_step_and_says_what_to_do() {
        let config = Config::default();
        let mut m = rt_machine();
        m.files.remove("/sys/kernel/realtime");
        m.files.insert(
            "/proc/sys/kernel/version",
            "#1 SMP PREEMPT_DYNAMIC\n".into(),
        );
        m.files
            .insert("/sys/devices/system/cpu/isolated", "\n".into());
        m.unit = Some("LoadState=loaded\nCPUAffinity=\nLimitMEMLOCK=65536\nLimitRTPRIO=0\n".into());
        m.link = Some(r#"[{"ifname":"can0","flags":["NOARP","UP"],"linkinfo":{"info_kind":"can","info_data":{"state":"ERROR-PASSIVE","berr_counter":{"tx":130,"rx":0},"bittiming":{"bitrate":500000}}}}]"#.into());
        m.files
            .insert("/proc/self/status", "Cpus_allowed_list:\t0-3\n".into());
        let steps = check(&config, &m);
        assert!(
            steps.iter().all(|s| s.verdict == Verdict::Fail),
            "{steps:#?}"
        );
        assert!(steps.iter().all(|s| s.wiring.is_some()), "{steps:#?}");
        assert!(steps[1].wiring.as_deref().unwrap().contains("isolcpus=1"));
        assert!(
            steps[4].measured.contains("500000"),
            "{}",
            steps[4].measured
        );
        // A down interface, and none at all.
        m.link =
            Some(r#"[{"ifname":"can0","flags":["NOARP"],"linkinfo":{"info_kind":"can"}}]"#.into());
        assert!(check(&config, &m)[4].measured.contains("is down"));
        m.link = None;
        assert!(check(&config, &m)[4]
            .measured
            .contains("no network interface can0"));
    }

    #[test]
    fn without_the_unit_this_process_limits_count() {
        let mut config = Config::default();
        let mut m = rt_machine();
        m.unit = None;
        m.files
            .insert("/proc/self/status", "Cpus_allowed_list:\t0,2-3\n".into());
        m.files.insert(
            "/proc/self/limits",
            "Max locked memory         8388608              8388608              bytes\nMax realtime priority     0                    0\n".into(),
        );
        let steps = check(&config, &m);
        assert_eq!(
            verdicts(&steps)[1..4],
            [
                ("computer.control-cpu".to_string(), Verdict::Fail),
                ("computer.memlock".to_string(), Verdict::Fail),
                ("computer.realtime-priority".to_string(), Verdict::Fail),
            ]
        );
        m.root = true;
        let steps = check(&config, &m);
        assert_eq!(steps[2].verdict, Verdict::Pass);
        assert_eq!(steps[3].verdict, Verdict::Pass);
        config.realtime.control_cpu = -1;
        assert_eq!(check(&config, &m)[1].verdict, Verdict::Skipped);
        assert_eq!(cpu_list("1-3, 5,x"), vec![1, 2, 3, 5]);
    }
}
