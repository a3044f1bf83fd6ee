//! The library's in-memory path: an analysis used straight from memory synthesizes exactly
//! what the same analysis gives after a round trip through its directory.

use btfsynth::analysis::pipeline::{analyze, AnalysisParams};
use btfsynth::analysis::store;
use btfsynth::btf::{
    self,
    gen::{GenParams, MaterialKind},
    DirectionSet,
};
use btfsynth::progress::Silent;
use btfsynth::synth::{plane::synthesize_plane, Sample, SynthParams};

#[test]
fn a_sample_from_memory_synthesizes_what_its_directory_does() {
    let params = GenParams {
        size: 32,
        samples_per_pixel: 1,
        directions: DirectionSet::Grid(4),
        ..GenParams::default()
    };
    let stack = btf::gen::generate(MaterialKind::Bricks, &params, &Silent).unwrap();
    let analysis =
        analyze(&stack, &AnalysisParams { textons: 48, levels: 2, ..AnalysisParams::default() }, &Silent)
            .unwrap();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("analysis");
    store::write(&analysis, &stack, std::path::Path::new("bricks"), None, &out, false).unwrap();
    let from_disk = Sample::open(&out, 2).unwrap();
    let from_memory = Sample::from_analysis(&analysis, &stack, 2).unwrap();
    for params in [SynthParams::default(), SynthParams { seed: 3, ..SynthParams::default() }] {
        let a = synthesize_plane(&from_disk, (48, 40), false, &params, &Silent).unwrap();
        let b = synthesize_plane(&from_memory, (48, 40), false, &params, &Silent).unwrap();
        assert_eq!((a.state.uv, a.state.labels), (b.state.uv, b.state.labels));
    }
    assert!(Sample::from_analysis(&analysis, &stack, 3).is_err(), "only the analysed levels exist");
}
