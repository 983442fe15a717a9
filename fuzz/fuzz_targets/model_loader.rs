#![no_main]

use std::panic;

libfuzzer_sys::fuzz_target!(
    init: {
        // `FcnModel::from_bytes` catches panics inside tract's ONNX importer and reports the
        // model as corrupt (fcn-infer's `malformed_models` test). libfuzzer-sys aborts on every
        // panic, caught or not, so panics raised in tract are let through to that guard. Every
        // other panic still aborts at once, and a tract panic that escapes the guard aborts in
        // libfuzzer-sys's own catch: both are reported as crashes.
        let abort = panic::take_hook();
        panic::set_hook(Box::new(move |info| {
            let in_tract = info
                .location()
                .is_some_and(|l| l.file().contains("/tract-"));
            if !in_tract {
                abort(info);
            }
        }));
    },
    |data: &[u8]| fuzz_replay::model_loader(data)
);
