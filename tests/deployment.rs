//! The deployment files are real: the Dockerfile is multi-stage, ships lavapipe and starts
//! `landsketch serve` with flags the server accepts; the Kubernetes example is valid YAML with
//! the expected kinds, readiness from `/api/health`, session affinity, and container flags and
//! environment variables that `landsketch serve` knows.

use clap::{CommandFactory, Parser};
use landsketch::api::ServerConfig;
use std::collections::BTreeSet;
use yaml_rust2::YamlLoader;

fn read(path: &str) -> String {
    std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{path}: {e}"))
}

/// The JSON-array ("exec form") arguments of the Dockerfile instruction `name`.
fn exec_form(dockerfile: &str, name: &str) -> Vec<String> {
    let line = dockerfile
        .lines()
        .find_map(|l| l.strip_prefix(name).and_then(|rest| rest.strip_prefix(' ')))
        .unwrap_or_else(|| panic!("the Dockerfile has no {name}"));
    serde_json::from_str(line).unwrap_or_else(|e| panic!("{name} is not in exec form: {e}"))
}

fn server_env_names() -> BTreeSet<String> {
    ServerConfig::command()
        .get_arguments()
        .filter_map(|a| a.get_env())
        .map(|e| e.to_string_lossy().into_owned())
        .collect()
}

#[test]
fn dockerfile_is_multi_stage_with_lavapipe_and_valid_server_flags() {
    let dockerfile = read("Dockerfile");
    let stages = dockerfile.lines().filter(|l| l.starts_with("FROM ")).count();
    assert!(stages >= 2, "a build stage and a runtime stage, found {stages}");
    assert!(dockerfile.contains("mesa-vulkan-drivers"), "lavapipe in the runtime image");
    assert!(dockerfile.contains("COPY --from=build"), "the runtime stage takes the built binary");
    let entry = exec_form(&dockerfile, "ENTRYPOINT");
    assert_eq!(entry, ["landsketch", "serve"]);
    let args = exec_form(&dockerfile, "CMD");
    let config = ServerConfig::try_parse_from(std::iter::once("landsketch serve".to_string()).chain(args))
        .unwrap_or_else(|e| panic!("the Dockerfile's CMD is not a valid `landsketch serve` command line: {e}"));
    assert!(!config.addr.ip().is_loopback(), "the container listens beyond loopback: {}", config.addr);
    assert!(std::path::Path::new(&config.scene).exists(), "the scene {} is in the image", config.scene.display());
    let env = dockerfile.lines().filter_map(|l| l.strip_prefix("ENV ")).collect::<Vec<_>>().join("\n");
    assert!(env.contains("XDG_RUNTIME_DIR="), "Vulkan's runtime directory is set");
}

#[test]
fn kubernetes_example_is_valid_with_probes_affinity_and_known_flags() {
    let docs = YamlLoader::load_from_str(&read("deploy/kubernetes/landsketch.yaml")).expect("valid YAML");
    let kinds: BTreeSet<&str> = docs.iter().filter_map(|d| d["kind"].as_str()).collect();
    for kind in ["Deployment", "Service", "StatefulSet", "Secret"] {
        assert!(kinds.contains(kind), "a {kind} in the example, found {kinds:?}");
    }
    for doc in &docs {
        assert!(doc["apiVersion"].as_str().is_some(), "every document has an apiVersion: {doc:?}");
        assert!(doc["metadata"]["name"].as_str().is_some(), "every document has a name");
    }
    let named = |kind: &str, name: &str| {
        docs.iter()
            .find(|d| d["kind"].as_str() == Some(kind) && d["metadata"]["name"].as_str() == Some(name))
            .unwrap_or_else(|| panic!("no {kind} {name}"))
    };
    let service = named("Service", "landsketch");
    assert_eq!(service["spec"]["sessionAffinity"].as_str(), Some("ClientIP"), "WebSockets stay on one pod");
    let deployment = named("Deployment", "landsketch");
    let labels = &deployment["spec"]["template"]["metadata"]["labels"];
    let selector = service["spec"]["selector"].as_hash().expect("the Service selects pods");
    for (k, v) in selector {
        assert_eq!(&labels[k.as_str().expect("label key")], v, "the Service selects the Deployment's pods");
    }
    // Several replicas on the shared database, each with a local copy of its data.
    assert!(deployment["spec"]["replicas"].as_i64().is_some_and(|n| n >= 2), "several replicas");
    let volumes = deployment["spec"]["template"]["spec"]["volumes"].as_vec().expect("volumes");
    let data = volumes.iter().find(|v| v["name"].as_str() == Some("data")).expect("a data volume");
    assert!(!data["emptyDir"].is_badvalue(), "the data directory is a local copy (emptyDir): {data:?}");
    let container = &deployment["spec"]["template"]["spec"]["containers"][0];
    assert_eq!(container["readinessProbe"]["httpGet"]["path"].as_str(), Some("/api/health"));
    let args: Vec<String> = container["args"]
        .as_vec()
        .expect("container args")
        .iter()
        .map(|a| a.as_str().expect("string args").to_string())
        .collect();
    ServerConfig::try_parse_from(std::iter::once("landsketch serve".to_string()).chain(args))
        .unwrap_or_else(|e| panic!("the container's args are not a valid `landsketch serve` command line: {e}"));
    let env = container["env"].as_vec().expect("container env");
    assert!(
        env.iter().any(|v| v["name"].as_str() == Some("LANDSKETCH_DATABASE_URL")),
        "the replicas share a PostgreSQL database"
    );
    let known = server_env_names();
    for var in container["env"].as_vec().expect("container env") {
        let name = var["name"].as_str().expect("env name");
        if name.starts_with("LANDSKETCH_") {
            assert!(known.contains(name), "`landsketch serve` reads no {name}; it knows {known:?}");
        }
    }
    // Every Secret a pod refers to is in the example.
    let secrets: BTreeSet<&str> = docs
        .iter()
        .filter(|d| d["kind"].as_str() == Some("Secret"))
        .filter_map(|d| d["metadata"]["name"].as_str())
        .collect();
    for volume in deployment["spec"]["template"]["spec"]["volumes"].as_vec().expect("volumes") {
        if let Some(secret) = volume["secret"]["secretName"].as_str() {
            assert!(secrets.contains(secret), "the Secret {secret} is defined");
        }
    }
}
