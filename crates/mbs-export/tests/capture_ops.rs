//! Spike: the operations each network's forward pass records.
#![allow(clippy::unwrap_used)]

use std::collections::BTreeMap;

use mbs_nets::network::{BackboneKind, NetworkConfig};

fn histogram(kind: BackboneKind, overrides: &[&str], height: usize, width: usize) {
    let overrides: Vec<String> = overrides.iter().map(|s| s.to_string()).collect();
    let config = NetworkConfig::with_overrides(kind, &overrides).unwrap();
    let network = config.init(&burn::tensor::Device::flex()).unwrap();
    let captured = mbs_export::capture::capture(&network, height, width).unwrap();
    let mut counts = BTreeMap::new();
    for op in &captured.graph.graph.operations {
        let text = format!("{op:?}");
        let name: String = text.chars().take_while(|c| *c != '{').collect::<String>();
        let name = name.split('(').take(2).collect::<Vec<_>>().join("(");
        *counts.entry(name).or_insert(0) += 1;
    }
    println!(
        "{kind:?}: {} ops, {} values, {} params",
        captured.graph.graph.operations.len(),
        captured.graph.values.len(),
        captured.parameter_names.len()
    );
    for (name, count) in counts {
        println!("  {count:5} {name}");
    }
}

#[test]
fn print_histograms() {
    histogram(BackboneKind::Compact, &[], 64, 128);
    histogram(
        BackboneKind::RaftStereo,
        &[
            "network.raft_stereo.hidden_dim=32",
            "network.raft_stereo.train_iters=2",
            "network.raft_stereo.test_iters=2",
        ],
        64,
        128,
    );
    histogram(
        BackboneKind::Igev,
        &[
            "network.igev.hidden_dim=32",
            "network.igev.test_iters=2",
            "network.igev.max_disp=64",
        ],
        64,
        128,
    );
}
