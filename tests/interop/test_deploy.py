"""The monitoring files under deploy/ against a running learner: Prometheus' own Python parser reads
the learner's /metrics; the scrape configuration points at the port compose publishes them on;
every metric the Grafana dashboard queries exists; the dashboard uses the provisioned data source;
the compose profiles that add Prometheus and Grafana are off by default and mount files that
exist. (promtool and Grafana themselves are images that cannot be pulled here.)"""

import json
import re
import shutil
import subprocess
import urllib.request

import pytest
import yaml
from prometheus_client.parser import text_string_to_metric_families

from conftest import ROOT, Learner, wait_for_file

DEPLOY = ROOT / "deploy"
DASHBOARD = DEPLOY / "grafana" / "dashboards" / "learner.json"
PROMQL_FUNCTIONS = {"rate", "irate", "increase", "sum", "avg", "max", "min", "by", "without", "count", "delta", "deriv"}


@pytest.fixture
def served_metrics(tmp_path):
    learner = Learner(tmp_path, extra=["--metrics-listen", "127.0.0.1:0"])
    try:
        addr = wait_for_file(learner.run_dir / "metrics.addr", learner.proc)
        with urllib.request.urlopen(f"http://{addr}/metrics", timeout=10) as response:
            assert response.headers["Content-Type"].startswith("text/plain; version=0.0.4")
            text = response.read().decode()
    finally:
        learner.stop()
    return text


def compose():
    return json.loads(json.dumps(yaml.safe_load((DEPLOY / "docker-compose.yml").read_text())))


def test_prometheus_parses_the_learners_metrics(served_metrics):
    families = {f.name: f for f in text_string_to_metric_families(served_metrics)}
    assert families["learner_updates"].type == "counter"
    assert families["learner_weights_version"].type == "gauge"
    assert families["learner_weights_version"].samples[0].value == 1


def test_the_dashboard_queries_only_metrics_the_learner_serves(served_metrics):
    families = list(text_string_to_metric_families(served_metrics))
    # Series names, and the names of families without series yet (per-actor gauges before actors).
    served = {s.name for f in families for s in f.samples} | {f.name for f in families if f.type == "gauge"}
    dashboard = json.loads(DASHBOARD.read_text())
    assert dashboard["uid"] and dashboard["title"] and dashboard["panels"]
    ids = [p["id"] for p in dashboard["panels"]]
    assert len(ids) == len(set(ids)), "panel ids must be unique"
    queried = set()
    for panel in dashboard["panels"]:
        g = panel["gridPos"]
        assert g["x"] >= 0 and g["w"] > 0 and g["x"] + g["w"] <= 24, panel["title"]
        assert panel["targets"], panel["title"]
        for target in panel["targets"]:
            for name in re.findall(r"[a-zA-Z_:][a-zA-Z0-9_:]*", re.sub(r"\{[^}]*\}|\[[^]]*\]|\"[^\"]*\"", "", target["expr"])):
                if name not in PROMQL_FUNCTIONS:
                    queried.add(name)
    missing = queried - served
    assert not missing, f"the dashboard queries metrics the learner does not serve: {sorted(missing)}"
    assert {"learner_loss", "learner_mean_q", "learner_episode_return_mean", "learner_weights_lag_mean"} <= queried


def test_the_dashboard_uses_the_provisioned_data_source():
    sources = yaml.safe_load((DEPLOY / "grafana/provisioning/datasources/prometheus.yml").read_text())["datasources"]
    uids = {s["uid"] for s in sources}
    assert [s["url"] for s in sources] == ["http://prometheus:9090"]
    dashboard = json.loads(DASHBOARD.read_text())
    for panel in dashboard["panels"]:
        assert panel["datasource"]["uid"] in uids, panel["title"]
        for target in panel["targets"]:
            assert target["datasource"]["uid"] in uids, panel["title"]
    providers = yaml.safe_load((DEPLOY / "grafana/provisioning/dashboards/hybrid-drive.yml").read_text())["providers"]
    grafana = compose()["services"]["grafana"]
    mounts = {v.split(":")[1]: v.split(":")[0] for v in grafana["volumes"]}
    assert mounts[providers[0]["options"]["path"]] == "./grafana/dashboards"


def test_the_scrape_configuration_targets_the_port_compose_serves_metrics_on():
    config = yaml.safe_load((DEPLOY / "prometheus" / "prometheus.yml").read_text())
    jobs = config["scrape_configs"]
    assert len(jobs) == 1 and jobs[0]["metrics_path"] == "/metrics"
    targets = [t for c in jobs[0]["static_configs"] for t in c["targets"]]
    services = compose()["services"]
    command = services["learner"]["command"]
    listen = command[command.index("--metrics-listen") + 1]
    assert targets == [f"learner:{listen.rsplit(':', 1)[1]}"], (targets, listen)
    prom = services["prometheus"]
    assert "./prometheus/prometheus.yml:/etc/prometheus/prometheus.yml:ro" in prom["volumes"]
    assert "--config.file=/etc/prometheus/prometheus.yml" in prom["command"]


def test_monitoring_is_off_by_default_and_mounts_files_that_exist():
    services = compose()["services"]
    assert "profiles" not in services["learner"] and "profiles" not in services["actor"]
    assert set(services["prometheus"]["profiles"]) == {"prometheus", "grafana"}
    assert services["grafana"]["profiles"] == ["grafana"]
    for name in ("prometheus", "grafana"):
        for volume in services[name]["volumes"]:
            source = volume.split(":")[0]
            if source.startswith("./"):
                assert (DEPLOY / source).exists(), f"{name} mounts {source}, which does not exist"
    docker_compose = (["docker", "compose"] if subprocess.run(["docker", "compose", "version"], capture_output=True).returncode == 0
                      else ["docker-compose"] if shutil.which("docker-compose") else None) if shutil.which("docker") or shutil.which("docker-compose") else None
    if docker_compose:
        for profile in ([], ["--profile", "grafana"]):
            done = subprocess.run([*docker_compose, "-f", str(DEPLOY / "docker-compose.yml"), *profile, "config", "-q"],
                                  capture_output=True, text=True)
            assert done.returncode == 0, done.stderr
