//! agent's integration tests, one program (one link) with a module per subject; sourcegen is its
//! own target (`UPDATE_SOURCEGEN=1 cargo test -p agent --test sourcegen` regenerates).

mod bf16;
mod candle_net;
