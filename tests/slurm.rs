//! A campaign through a real Slurm scheduler (README "Campaigns on a cluster"): the test
//! starts a single-node cluster of its own (munged on a private socket and key, slurmctld
//! and slurmd with a minimal slurm.conf: the node at 127.0.0.1, proctrack/linuxproc,
//! task/none, select/cons_tres, private ports and state directories), submits the
//! scripts of examples/slurm/ and stops every daemon it started, also when it fails
//! (a guard's Drop). Needs root and Debian's slurm-wlm and munge: in CI (`CI` or
//! `LATDYN_REQUIRE_SLURM` set; .ci/run installs them) their absence fails the test,
//! elsewhere it prints SKIPPED.
//!
//! 1. A 4-task array over 48 variants and the dependent merge job: the merged file equals
//!    a single-process sweep of the campaign, bit for bit.
//! 2. A second array of the same campaign, one task cancelled (scancel) mid-run: the
//!    merge job reports exactly that task's unfinished global indices and exits 4; the
//!    resume job completes the merged file to the single-process values.

mod common;

use common::assert_same_campaign;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// `name` in PATH or /usr/sbin (slurmctld, slurmd and munged live there).
fn find(name: &str) -> Option<PathBuf> {
    let path = std::env::var_os("PATH").unwrap_or_default();
    std::env::split_paths(&path)
        .chain([PathBuf::from("/usr/sbin"), PathBuf::from("/sbin")])
        .map(|d| d.join(name))
        .find(|p| p.is_file())
}

fn is_root() -> bool {
    Command::new("id")
        .arg("-u")
        .output()
        .map(|o| String::from_utf8_lossy(&o.stdout).trim() == "0")
        .unwrap_or(false)
}

/// The daemons of a private single-node cluster; dropping it cancels its jobs and stops
/// them (SIGTERM, then SIGKILL after 10 s), newest first.
struct Cluster {
    dir: PathBuf,
    conf: PathBuf,
    daemons: Vec<(&'static str, Child)>,
}

impl Cluster {
    fn start(dir: &Path) -> Cluster {
        let _ = std::fs::remove_dir_all(dir);
        for d in ["state", "spool", "log"] {
            std::fs::create_dir_all(dir.join(d)).unwrap();
        }
        let mut c = Cluster {
            dir: dir.to_path_buf(),
            conf: dir.join("slurm.conf"),
            daemons: Vec::new(),
        };
        // a key of our own: munged checks that only its owner can read it
        let key: Vec<u8> = (0..1024u32)
            .map(|i| (i.wrapping_mul(2_654_435_761) >> 13) as u8 ^ std::process::id() as u8)
            .collect();
        let key_path = dir.join("munge.key");
        std::fs::write(&key_path, key).unwrap();
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(&key_path, std::fs::Permissions::from_mode(0o600)).unwrap();
        std::fs::set_permissions(dir, std::fs::Permissions::from_mode(0o700)).unwrap();
        let sock = dir.join("munge.sock");
        c.spawn(
            "munged",
            Command::new(find("munged").unwrap()).args([
                "-F",
                "--force",
                &format!("--socket={}", s(&sock)),
                &format!("--key-file={}", s(&key_path)),
                &format!("--log-file={}", s(&dir.join("log/munged.log"))),
                &format!("--pid-file={}", s(&dir.join("munged.pid"))),
                &format!("--seed-file={}", s(&dir.join("munged.seed"))),
            ]),
        );
        c.wait_for("the munge socket", 20, |c| {
            c.dir.join("munge.sock").exists()
        });
        let port = 17_000 + (std::process::id() % 1000) * 2;
        let host = Command::new("hostname")
            .output()
            .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_string())
            .unwrap_or_else(|_| "localhost".into());
        let cpus = std::thread::available_parallelism().map_or(1, |n| n.get());
        let d = s(dir);
        let conf = format!(
            "ClusterName=latdyntest\n\
             SlurmctldHost=localhost(127.0.0.1)\n\
             SlurmctldPort={port}\n\
             SlurmdPort={}\n\
             SlurmUser=root\n\
             SlurmdUser=root\n\
             AuthType=auth/munge\n\
             CredType=cred/munge\n\
             AuthInfo=socket={d}/munge.sock\n\
             StateSaveLocation={d}/state\n\
             SlurmdSpoolDir={d}/spool\n\
             SlurmctldPidFile={d}/slurmctld.pid\n\
             SlurmdPidFile={d}/slurmd.pid\n\
             SlurmctldLogFile={d}/log/slurmctld.log\n\
             SlurmdLogFile={d}/log/slurmd.log\n\
             ProctrackType=proctrack/linuxproc\n\
             TaskPlugin=task/none\n\
             SelectType=select/cons_tres\n\
             SelectTypeParameters=CR_Core\n\
             MpiDefault=none\n\
             JobAcctGatherType=jobacct_gather/none\n\
             AccountingStorageType=accounting_storage/none\n\
             ReturnToService=2\n\
             KillWait=10\n\
             MinJobAge=600\n\
             NodeName=latdyn0 NodeHostname={host} NodeAddr=127.0.0.1 CPUs={cpus} State=UNKNOWN\n\
             PartitionName=test Nodes=ALL Default=YES MaxTime=INFINITE State=UP\n",
            port + 1
        );
        std::fs::write(&c.conf, conf).unwrap();
        let conf = c.conf.clone();
        c.spawn(
            "slurmctld",
            Command::new(find("slurmctld").unwrap()).args(["-D", "-i", "-f", s(&conf)]),
        );
        c.spawn(
            "slurmd",
            Command::new(find("slurmd").unwrap()).args(["-D", "-N", "latdyn0", "-f", s(&conf)]),
        );
        c.wait_for("the node idle", 60, |c| {
            c.cmd("sinfo")
                .args(["-h", "-o", "%t"])
                .output()
                .is_ok_and(|o| String::from_utf8_lossy(&o.stdout).trim() == "idle")
        });
        c
    }

    fn spawn(&mut self, name: &'static str, cmd: &mut Command) {
        let log = std::fs::File::create(self.dir.join(format!("log/{name}.out"))).unwrap();
        let child = cmd
            .env("SLURM_CONF", &self.conf)
            .stdin(Stdio::null())
            .stdout(log.try_clone().unwrap())
            .stderr(log)
            .spawn()
            .unwrap_or_else(|e| panic!("starting {name}: {e}"));
        self.daemons.push((name, child));
    }

    /// A Slurm client command talking to this cluster.
    fn cmd(&self, name: &str) -> Command {
        let mut c = Command::new(find(name).unwrap_or_else(|| PathBuf::from(name)));
        c.env("SLURM_CONF", &self.conf);
        c
    }

    fn logs(&self) -> String {
        let mut out = String::new();
        for f in [
            "slurmctld.log",
            "slurmd.log",
            "munged.log",
            "slurmctld.out",
            "slurmd.out",
        ] {
            let text = std::fs::read_to_string(self.dir.join("log").join(f)).unwrap_or_default();
            let tail: Vec<&str> = text.lines().rev().take(15).collect();
            out += &format!("--- {f} (last lines)\n");
            for l in tail.into_iter().rev() {
                out += l;
                out += "\n";
            }
        }
        out
    }

    fn wait_for(&mut self, what: &str, secs: u64, mut cond: impl FnMut(&Cluster) -> bool) {
        let deadline = Instant::now() + Duration::from_secs(secs);
        while !cond(self) {
            let dead = self
                .daemons
                .iter_mut()
                .find_map(|(name, child)| match child.try_wait() {
                    Ok(Some(st)) => Some(format!("{name} exited ({st})")),
                    _ => None,
                });
            if let Some(dead) = dead {
                panic!("{dead} waiting for {what}\n{}", self.logs());
            }
            if Instant::now() > deadline {
                panic!(
                    "timed out after {secs} s waiting for {what}\n{}",
                    self.logs()
                );
            }
            std::thread::sleep(Duration::from_millis(50));
        }
    }

    /// Wait until job `id` (and every task of it) has left the queue.
    fn wait_job(&mut self, id: &str, secs: u64) {
        self.wait_for(&format!("job {id} to end"), secs, |c| {
            c.cmd("squeue")
                .args(["-h", "-j", id, "-o", "%i"])
                .output()
                .is_ok_and(|o| {
                    o.status.success() && o.stdout.iter().all(|b| b.is_ascii_whitespace())
                })
        });
    }

    /// `ExitCode=N:S` of a finished job (kept by slurmctld for MinJobAge).
    fn exit_code(&self, id: &str) -> String {
        let out = self
            .cmd("scontrol")
            .args(["show", "job", id])
            .output()
            .unwrap();
        let text = String::from_utf8_lossy(&out.stdout).into_owned();
        text.split_whitespace()
            .find_map(|w| w.strip_prefix("ExitCode="))
            .unwrap_or_else(|| panic!("no ExitCode in {text}"))
            .to_string()
    }
}

impl Drop for Cluster {
    fn drop(&mut self) {
        let _ = self.cmd("scancel").args(["--full", "-u", "root"]).status();
        let deadline = Instant::now() + Duration::from_secs(15);
        while Instant::now() < deadline
            && self
                .cmd("squeue")
                .args(["-h", "-o", "%i"])
                .output()
                .is_ok_and(|o| !o.stdout.iter().all(|b| b.is_ascii_whitespace()))
        {
            std::thread::sleep(Duration::from_millis(100));
        }
        for (_, child) in self.daemons.iter_mut().rev() {
            let _ = Command::new("kill")
                .args(["-s", "TERM", &child.id().to_string()])
                .status();
            let deadline = Instant::now() + Duration::from_secs(10);
            while Instant::now() < deadline && matches!(child.try_wait(), Ok(None)) {
                std::thread::sleep(Duration::from_millis(50));
            }
            if matches!(child.try_wait(), Ok(None)) {
                let _ = child.kill();
            }
            let _ = child.wait();
        }
    }
}

fn completed_rows(path: &Path) -> Vec<usize> {
    let Some(f) = path
        .exists()
        .then(|| rust_hdf5::H5File::open(path).ok())
        .flatten()
    else {
        return Vec::new();
    };
    let state = f.dataset("status/state").and_then(|d| d.read_raw::<i32>());
    let gi = f
        .dataset("status/global_index")
        .and_then(|d| d.read_raw::<i64>());
    match (state, gi) {
        (Ok(st), Ok(gi)) => st
            .iter()
            .zip(gi)
            .filter(|(s, _)| **s == 2)
            .map(|(_, g)| g as usize)
            .collect(),
        _ => Vec::new(),
    }
}

const SHARDS: usize = 4;
const VARIANTS: usize = 48;

#[test]
fn slurm_array_merge_equals_the_single_sweep_and_a_cancelled_task_is_resumed() {
    let required =
        std::env::var_os("CI").is_some() || std::env::var_os("LATDYN_REQUIRE_SLURM").is_some();
    let missing: Vec<&str> = [
        "munged",
        "slurmctld",
        "slurmd",
        "sbatch",
        "squeue",
        "scancel",
        "scontrol",
        "sinfo",
    ]
    .into_iter()
    .filter(|b| find(b).is_none())
    .collect();
    let h5py = Command::new("python3")
        .args(["-c", "import h5py"])
        .output()
        .is_ok_and(|o| o.status.success());
    let why = if !missing.is_empty() {
        Some(format!(
            "missing {} (apt-get install slurm-wlm munge)",
            missing.join(", ")
        ))
    } else if !is_root() {
        Some("the test cluster's daemons need root".to_string())
    } else if !h5py {
        Some("h5py is not installed".to_string())
    } else {
        None
    };
    if let Some(why) = why {
        assert!(!required, "Slurm test required in CI, but {why}");
        println!("SKIPPED: {why}");
        return;
    }
    let work = Path::new(env!("CARGO_TARGET_TMPDIR")).join("slurm");
    let mut cluster = Cluster::start(&work.join("cluster"));
    let latdyn = PathBuf::from(env!("CARGO_BIN_EXE_latdyn"));
    let model = root().join("models/rotating_cantilever.toml");
    // 48 variants of ~0.5-1 s each (test profile): a task of 12 runs ~10 s, so it can be
    // cancelled after its first flush (2 s after its first variant) and well before its
    // end. (With t_end = 4 a task took ~2.5 s on an idle machine and sometimes finished
    // before the cancel arrived.) `--batch 1`: variants then finish one by one; in lockstep
    // batches a task's variants finish together, and once the SIMD-lane stage made them
    // faster the task's last batch ended before the cancel arrived (session 21).
    let campaign = format!(
        "{} --vary omega=1:5:{VARIANTS} --set t_end=20 --set dt=0.01 --batch 1",
        s(&model)
    );

    let reference = work.join("single.h5");
    let _ = std::fs::remove_file(&reference);
    let mut args: Vec<&str> = vec!["sweep"];
    args.extend(campaign.split(' '));
    args.extend(["-o", s(&reference)]);
    let o = Command::new(&latdyn).args(&args).output().unwrap();
    assert_eq!(
        o.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );

    let submit = |cluster: &Cluster, out: &Path| -> (String, String) {
        let _ = std::fs::remove_dir_all(out);
        let o = cluster
            .cmd("bash")
            .arg(root().join("examples/slurm/submit.sh"))
            .env("LATDYN", &latdyn)
            .env("CAMPAIGN", &campaign)
            .env("SHARDS", SHARDS.to_string())
            .env("OUT", out)
            .output()
            .unwrap();
        let text = String::from_utf8_lossy(&o.stdout).into_owned();
        assert!(
            o.status.success(),
            "submit.sh: {text}{}",
            String::from_utf8_lossy(&o.stderr)
        );
        let ids: Vec<&str> = text.split_whitespace().collect();
        assert_eq!(ids.len(), 2, "submit.sh printed {text:?}");
        (ids[0].to_string(), ids[1].to_string())
    };
    let report = |out: &Path| -> serde_json::Value {
        let text = std::fs::read_to_string(out.join("merge.json")).unwrap_or_default();
        serde_json::from_str(&text).unwrap_or_else(|e| {
            panic!(
                "merge.json: {e}: {text:?}; merge.log: {}",
                std::fs::read_to_string(out.join("merge.log")).unwrap_or_default()
            )
        })
    };
    let list = |v: &serde_json::Value| -> Vec<usize> {
        v.as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_u64().unwrap() as usize)
            .collect()
    };

    // 1. the whole array, then the merge job it releases
    let out1 = work.join("run1");
    let (array, merge) = submit(&cluster, &out1);
    cluster.wait_job(&array, 300);
    cluster.wait_job(&merge, 120);
    assert_eq!(cluster.exit_code(&merge), "0:0");
    let r = report(&out1);
    assert_eq!(r["status"], "complete", "{r}");
    assert_eq!(r["completed"], VARIANTS);
    assert_eq!(r["shards"].as_array().unwrap().len(), SHARDS);
    assert_same_campaign(&reference, &out1.join("campaign.h5"));

    // 2. the same campaign again; task 2 cancelled once its first variants are flushed
    let out2 = work.join("run2");
    let (array, merge) = submit(&cluster, &out2);
    let shard2 = out2.join("shard_2.h5");
    cluster.wait_for("task 2's first flushed variant", 300, |_| {
        !completed_rows(&shard2).is_empty()
    });
    let o = cluster
        .cmd("scancel")
        .arg(format!("{array}_2"))
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    cluster.wait_job(&array, 300);
    cluster.wait_job(&merge, 120);
    let done = completed_rows(&shard2);
    let task2: Vec<usize> = (0..VARIANTS).filter(|g| g % SHARDS == 1).collect();
    let unfinished: Vec<usize> = task2
        .iter()
        .copied()
        .filter(|g| !done.contains(g))
        .collect();
    assert!(
        !done.is_empty() && !unfinished.is_empty(),
        "cancelled mid-run: completed {done:?} of {task2:?}"
    );
    let f = rust_hdf5::H5File::open(&shard2).unwrap();
    assert_eq!(
        f.attr_string("status").unwrap(),
        "interrupted",
        "SIGTERM from scancel: the shard file is marked interrupted"
    );
    drop(f);
    assert_eq!(cluster.exit_code(&merge), "4:0", "merge exit 4: incomplete");
    let r = report(&out2);
    assert_eq!(r["status"], "incomplete", "{r}");
    assert_eq!(list(&r["to_resume"]), unfinished, "{r}");
    let mut open = list(&r["missing"]);
    open.extend(list(&r["interrupted"]));
    open.sort_unstable();
    assert_eq!(open, unfinished, "{r}");
    assert!(list(&r["failed"]).is_empty() && list(&r["duplicated"]).is_empty());

    // 3. the resume job completes the merged file in place
    let o = cluster
        .cmd("sbatch")
        .args(["--wait", "--parsable"])
        .arg(format!("--output={}", s(&out2.join("resume.log"))))
        .arg(root().join("examples/slurm/resume.sbatch"))
        .env("LATDYN", &latdyn)
        .env("CAMPAIGN", &campaign)
        .env("OUT", &out2)
        .output()
        .unwrap();
    assert!(
        o.status.success(),
        "resume job: {}{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr),
        std::fs::read_to_string(out2.join("resume.log")).unwrap_or_default()
    );
    assert_same_campaign(&reference, &out2.join("campaign.h5"));
    drop(cluster);
}
