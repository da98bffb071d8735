//! The flags every client command shares (`actor --learner`, `learner status`, `learner health`):
//! TLS files, the token file and the plaintext override, turned into a [`Target`] and a token
//! here, once, so that no command builds its own connection.

use std::path::PathBuf;

use crate::client::{ClientError, read_token};
use crate::target::{Target, TargetError, TlsFiles};

/// TLS towards the learner: on with `--tls-ca` (or an `https://` address, which needs it).
#[derive(Debug, Clone, Default, clap::Args)]
pub struct TlsArgs {
    /// PEM certificate of the CA that signed the learner's certificate: turns TLS on (the
    /// address may then be HOST:PORT or https://HOST:PORT).
    #[arg(long, value_name = "FILE")]
    pub tls_ca: Option<PathBuf>,
    /// This client's PEM certificate, for a learner that requires one (mutual TLS; with
    /// --tls-key).
    #[arg(long, value_name = "FILE", requires_all = ["tls_key", "tls_ca"])]
    pub tls_cert: Option<PathBuf>,
    /// The private key of --tls-cert (PEM).
    #[arg(long, value_name = "FILE", requires = "tls_cert")]
    pub tls_key: Option<PathBuf>,
}

impl TlsArgs {
    /// The files, when TLS is asked for.
    #[must_use]
    pub fn files(&self) -> Option<TlsFiles> {
        let ca = self.tls_ca.clone()?;
        Some(TlsFiles { ca, identity: self.tls_cert.clone().zip(self.tls_key.clone()) })
    }

    /// The target at `addr` with these TLS files (no token to guard).
    pub fn target(&self, addr: &str) -> Result<Target, TargetError> {
        Target::new(addr, self.files(), false)
    }
}

/// The bearer token and the one override of the rule that it never travels in clear.
#[derive(Debug, Clone, Default, clap::Args)]
pub struct AuthArgs {
    /// Token file, if the learner requires one (its first line). Sent over plaintext only to a
    /// loopback address, unless --insecure-plaintext.
    #[arg(long, value_name = "FILE")]
    pub auth_token_file: Option<PathBuf>,
    /// Send the token over plaintext to a non-loopback address anyway (a network you trust
    /// entirely); without it such a connection is refused before it is made.
    #[arg(long)]
    pub insecure_plaintext: bool,
}

impl AuthArgs {
    /// The token, read from its file.
    pub fn token(&self) -> Result<Option<String>, ClientError> {
        self.auth_token_file.as_deref().map(read_token).transpose()
    }

    /// The target at `addr` with `tls`, carrying the override; checked against the token rule
    /// now, before anything connects.
    pub async fn target(&self, addr: &str, tls: &TlsArgs) -> Result<(Target, Option<String>), ClientError> {
        let target = Target::new(addr, tls.files(), self.insecure_plaintext)?;
        let token = self.token()?;
        if token.is_some() {
            target.check_token_safety().await?;
        }
        Ok((target, token))
    }
}
