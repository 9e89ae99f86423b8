//! `iceoryx2`: the bus's own bookkeeping — nodes (one per process on the bus) and services.
//!
//! A process that crashes leaves its node's files behind in `/dev/shm` and the iceoryx2 root
//! directory. They do no harm by themselves, and robotd removes them when it starts, but many
//! of them point at an actor that keeps crashing. The check lists the nodes (live, dead, not
//! ours to read, damaged) and counts the services of robotd's namespace; with
//! `robotd doctor --clean` it removes the dead nodes' resources.
//!
//! The bus itself uses `ipc_threadsafe::Service`; it shares every file (node monitors, node
//! details, service storage) with `ipc::Service`, so listing and cleaning with `ipc::Service`
//! sees and removes the same resources.

use super::{Check, Status};
use iceoryx2::node::NodeView;
use iceoryx2::prelude::*;
use robotd_runtime::bus::stale;

/// Same rule as the runtime's bus: 1-64 characters from A-Z, a-z, 0-9, '_' and '-'.
fn valid_namespace(namespace: &str) -> bool {
    !namespace.is_empty()
        && namespace.len() <= 64
        && namespace
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-')
}

fn describe_node(details: &Option<iceoryx2::node::NodeDetails>) -> String {
    match details {
        Some(d) if !d.name().as_str().is_empty() => {
            format!("'{}' pid {}", d.name().as_str(), d.process_id())
        }
        Some(d) => format!("pid {}", d.process_id()),
        None => "unknown".to_owned(),
    }
}

pub(super) fn check_bus(config: &Config, namespace: &str, clean: bool) -> Check {
    const NAME: &str = "iceoryx2";
    if !valid_namespace(namespace) {
        return Check::problem(
            NAME,
            format!("bus namespace '{namespace}' is not valid; robotd would refuse to start"),
            "use 1-64 characters from A-Z, a-z, 0-9, '_' and '-' for the bus namespace",
        );
    }

    // iceoryx2 waits forever on a segment a killed process left half-created; such a segment
    // made listing the services below hang.
    let half_created = stale::remove_half_created(
        std::path::Path::new(stale::SHARED_MEMORY_DIR),
        stale::HALF_CREATED_AFTER,
    );
    let mut alive = 0usize;
    let mut dead = Vec::new();
    let mut inaccessible = 0usize;
    let mut undefined = 0usize;
    let listed = Node::<ipc::Service>::list(config, |state| {
        match state {
            NodeState::Alive(_) => alive += 1,
            NodeState::Dead(view) => dead.push(view),
            NodeState::Inaccessible(_) => inaccessible += 1,
            NodeState::Undefined(_) => undefined += 1,
        }
        CallbackProgression::Continue
    });
    if let Err(e) = listed {
        return Check::warn(
            NAME,
            format!("could not list iceoryx2 nodes ({e})"),
            "run `robotd doctor` as the user that runs robotd (or as root)",
        );
    }

    let prefix = format!("{namespace}/");
    let mut services = 0usize;
    let services_listed = ipc::Service::list(config, |details| {
        if details.static_details.name().as_str().starts_with(&prefix) {
            services += 1;
        }
        CallbackProgression::Continue
    });
    let services_text = match services_listed {
        Ok(()) => format!("{services} services in namespace '{namespace}'"),
        Err(e) => format!("services not listed ({e:?})"),
    };

    let dead_names: Vec<String> = dead
        .iter()
        .take(5)
        .map(|v| describe_node(v.details()))
        .collect();
    let dead_text = if dead.is_empty() {
        "0 dead".to_owned()
    } else {
        let more = if dead.len() > dead_names.len() {
            ", ..."
        } else {
            ""
        };
        format!("{} dead ({}{more})", dead.len(), dead_names.join(", "))
    };

    let mut notes = Vec::new();
    let mut status = Status::Ok;
    let mut fixes = Vec::new();

    if clean && !dead.is_empty() {
        let total = dead.len();
        let mut removed = 0usize;
        let mut failures = Vec::new();
        for view in dead {
            match view.try_remove_stale_resources() {
                Ok(()) | Err(iceoryx2::node::NodeCleanupFailure::ResourcesAlreadyCleanedUp) => {
                    removed += 1
                }
                Err(e) => failures.push(format!("{e:?}")),
            }
        }
        notes.push(format!(
            "nodes: {alive} live, {total} dead, removed the resources of {removed}"
        ));
        if !failures.is_empty() {
            status = Status::Problem;
            notes.push(format!(
                "{} could not be removed ({})",
                failures.len(),
                failures.join(", ")
            ));
            fixes.push(
                "run `robotd doctor --clean` as the user that owns them (or as root), \
                 with no other process cleaning at the same time"
                    .to_owned(),
            );
        }
    } else {
        notes.push(format!("nodes: {alive} live, {dead_text}"));
        if !dead.is_empty() {
            status = Status::Warn;
            fixes.push("robotd cleans them at start; or run `robotd doctor --clean`".to_owned());
        }
    }
    if inaccessible > 0 {
        status = status.max(Status::Warn);
        notes.push(format!(
            "{inaccessible} nodes not accessible (another user's processes)"
        ));
        fixes.push("run `robotd doctor` as that user (or as root) to inspect or clean them".into());
    }
    if undefined > 0 {
        status = status.max(Status::Warn);
        notes.push(format!(
            "{undefined} nodes in an undefined state (damaged files)"
        ));
        fixes.push(format!(
            "stop every iceoryx2 process, then remove {}* and /dev/shm/{}*",
            config.global.root_path(),
            config.global.prefix
        ));
    }
    notes.push(services_text);
    if !half_created.is_empty() {
        notes.push(format!(
            "removed {} half-created segments a killed process left in {} (they made iceoryx2 hang)",
            half_created.len(),
            stale::SHARED_MEMORY_DIR
        ));
    }

    Check {
        name: NAME,
        status,
        found: notes.join("; "),
        fix: if fixes.is_empty() {
            None
        } else {
            Some(fixes.join("; "))
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::{Path, PathBuf};
    use std::process::{Command, Stdio};

    #[test]
    fn bad_namespace_is_a_problem() {
        let check = check_bus(Config::global_config(), "has space", false);
        assert_eq!(check.status, Status::Problem);
    }

    /// An iceoryx2 config whose files do not meet anyone else's (own prefix).
    fn isolated_config(prefix: &str) -> Config {
        let mut config = Config::global_config().clone();
        config.global.prefix = FileName::new(prefix.as_bytes()).expect("valid prefix");
        config
    }

    const DIE_ENV: &str = "ROBOTD_DOCTOR_TEST_DIE_PREFIX";

    /// Helper run in a child process by `bus_dead_nodes_are_reported_and_cleaned`: creates a
    /// node and exits without cleaning up, as a crashed actor would. Does nothing otherwise.
    #[test]
    #[ignore = "helper: run by bus_dead_nodes_are_reported_and_cleaned in a child process"]
    fn bus_helper_create_node_and_die() {
        let Ok(prefix) = std::env::var(DIE_ENV) else {
            return;
        };
        let config = isolated_config(&prefix);
        let node = NodeBuilder::new()
            .name(&NodeName::new("doctor-test-dead").expect("name"))
            .config(&config)
            .create::<ipc::Service>()
            .expect("create node");
        let _service = node
            .service_builder(&ServiceName::new("doctortest/topic").expect("service name"))
            .publish_subscribe::<u64>()
            .open_or_create()
            .expect("service");
        std::mem::forget(node);
        // SAFETY: ends this helper process at once, skipping every destructor on purpose.
        unsafe { libc::_exit(0) };
    }

    /// Removes every file the isolated config left in /dev/shm and the iceoryx2 root directory.
    struct PrefixCleanup {
        prefix: String,
        root: PathBuf,
    }

    impl Drop for PrefixCleanup {
        fn drop(&mut self) {
            fn sweep(dir: &Path, prefix: &str, depth: u32) {
                let Ok(entries) = std::fs::read_dir(dir) else {
                    return;
                };
                for entry in entries.flatten() {
                    let path = entry.path();
                    if entry.file_name().to_string_lossy().starts_with(prefix) {
                        let _ = std::fs::remove_file(&path);
                        let _ = std::fs::remove_dir_all(&path);
                    } else if depth > 0 && path.is_dir() {
                        sweep(&path, prefix, depth - 1);
                    }
                }
            }
            sweep(Path::new("/dev/shm"), &self.prefix, 0);
            sweep(&self.root, &self.prefix, 3);
        }
    }

    #[test]
    fn bus_dead_nodes_are_reported_and_cleaned() {
        let prefix = format!("rdoc{}_", std::process::id());
        let config = isolated_config(&prefix);
        let _cleanup = PrefixCleanup {
            prefix: prefix.clone(),
            root: PathBuf::from(config.global.root_path().to_string()),
        };

        let empty = check_bus(&config, "doctortest", false);
        assert_eq!(empty.status, Status::Ok, "{empty:?}");
        assert!(
            empty.found.contains("nodes: 0 live, 0 dead"),
            "{}",
            empty.found
        );

        // A live node in this process, with a service in the namespace.
        let live = NodeBuilder::new()
            .config(&config)
            .create::<ipc::Service>()
            .expect("create node");
        let _service = live
            .service_builder(&ServiceName::new("doctortest/live").expect("service name"))
            .publish_subscribe::<u64>()
            .open_or_create()
            .expect("service");
        let check = check_bus(&config, "doctortest", false);
        assert_eq!(check.status, Status::Ok, "{check:?}");
        assert!(
            check.found.contains("nodes: 1 live, 0 dead"),
            "{}",
            check.found
        );
        assert!(
            check.found.contains("1 services in namespace 'doctortest'"),
            "{}",
            check.found
        );

        // A crashed process leaves a dead node behind.
        let exe = std::env::current_exe().expect("test binary");
        let status = Command::new(exe)
            .args([
                "doctor::bus::tests::bus_helper_create_node_and_die",
                "--exact",
                "--ignored",
                "--test-threads=1",
            ])
            .env(DIE_ENV, &prefix)
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .status()
            .expect("run helper");
        assert!(status.success(), "helper failed: {status}");

        let check = check_bus(&config, "doctortest", false);
        assert_eq!(check.status, Status::Warn, "{check:?}");
        assert!(
            check.found.contains("1 dead ('doctor-test-dead' pid"),
            "{}",
            check.found
        );
        assert!(check
            .fix
            .as_deref()
            .unwrap_or("")
            .contains("robotd doctor --clean"));

        let cleaned = check_bus(&config, "doctortest", true);
        assert_eq!(cleaned.status, Status::Ok, "{cleaned:?}");
        assert!(
            cleaned.found.contains("removed the resources of 1"),
            "{}",
            cleaned.found
        );

        let after = check_bus(&config, "doctortest", false);
        assert_eq!(after.status, Status::Ok, "{after:?}");
        assert!(
            after.found.contains("nodes: 1 live, 0 dead"),
            "{}",
            after.found
        );
    }
}
