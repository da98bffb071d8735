//! Telling connection failures apart: a transport error's chain (tonic → hyper → h2 → io →
//! rustls) turned into one sentence that says what went wrong and what to change — the wrong CA,
//! an expired or not-yet-valid certificate, a hostname mismatch, plaintext against TLS or the
//! reverse, a client certificate the learner wants or refuses.

use std::error::Error;

use rustls::{AlertDescription, CertificateError};

/// What a client was doing when it failed.
#[derive(Debug, Clone, Copy)]
pub struct Attempt<'a> {
    /// It spoke TLS (else plaintext).
    pub tls: bool,
    /// It presented a client certificate.
    pub client_cert: bool,
    /// The host it connected to (the name the certificate must be valid for).
    pub host: &'a str,
    /// The connection (TCP, and TLS from this side's view) was made; the first exchange failed.
    pub connected: bool,
}

/// What the chain of `err` says about `attempt`.
#[must_use]
pub fn describe(err: &(dyn Error + 'static), attempt: &Attempt<'_>) -> String {
    let (tls, host) = (attempt.tls, attempt.host);
    let chain = chain(err);
    if let Some(r) = chain.iter().find_map(|e| rustls_error(*e)) {
        return describe_rustls(r, host);
    }
    let text: String = chain.iter().map(|e| e.to_string().to_lowercase()).collect::<Vec<_>>().join(": ");
    let detail = chain.last().map(ToString::to_string).unwrap_or_default();
    // After a TLS 1.3 handshake that succeeded on this side, the server judges the client's
    // certificate; its alert often reaches the client only as text (h2 keeps io errors as
    // strings) or not at all (the connection is closed under the first request, which the
    // channel may report only as "connection was not ready").
    if tls && attempt.connected {
        let lost = ["eof", "reset", "closed", "broken pipe", "alert", "not ready"].iter().any(|w| text.contains(w));
        if text.contains("certificaterequired") || (lost && !attempt.client_cert) {
            return describe_rustls(&rustls::Error::AlertReceived(AlertDescription::CertificateRequired), host);
        }
        if lost {
            return format!(
                "the learner refused this client's certificate ({detail}): it must be signed by the CA the learner trusts \
                 (its --tls-client-ca) and valid now"
            );
        }
    }
    if text.contains("connection refused") {
        return format!("connection refused: nothing listens there ({detail})");
    }
    // "end of file": an `io::ErrorKind::UnexpectedEof`'s own text, which names no "eof".
    let ended = ["eof", "end of file", "reset", "closed", "broken pipe"].iter().any(|w| text.contains(w));
    if tls && ended {
        return format!(
            "the server closed the connection during the TLS handshake: it may serve plaintext (then connect with http:// and \
             no --tls-ca) ({detail})"
        );
    }
    if tls && text.contains("h2 was not negotiated") {
        return "the server's TLS does not offer HTTP/2 (ALPN h2): it is not a gRPC server".into();
    }
    if !tls && (ended || ["frame", "protocol", "not http", "malformed"].iter().any(|w| text.contains(w))) {
        return format!(
            "the server ended the connection without speaking HTTP/2 in clear: it may serve TLS (then connect with \
             https://HOST:PORT and --tls-ca FILE) ({detail})"
        );
    }
    detail
}

/// The errors of a chain, outermost first, looking inside `io::Error`s too (whose `source()`
/// skips the error they wrap).
fn chain<'a>(err: &'a (dyn Error + 'static)) -> Vec<&'a (dyn Error + 'static)> {
    let mut out = Vec::new();
    let mut next = Some(err);
    while let Some(e) = next {
        out.push(e);
        next = match e.downcast_ref::<std::io::Error>().and_then(|io| io.get_ref()) {
            Some(inner) => Some(inner as &(dyn Error + 'static)),
            None => e.source(),
        };
    }
    out
}

fn rustls_error<'a>(e: &'a (dyn Error + 'static)) -> Option<&'a rustls::Error> {
    e.downcast_ref::<rustls::Error>()
}

fn describe_rustls(e: &rustls::Error, host: &str) -> String {
    use rustls::Error as E;
    match e {
        E::InvalidCertificate(c) => match c {
            // A CA of the same name that did not sign it (two `learner certs` runs) is a bad
            // signature rather than an unknown issuer: the same mistake.
            CertificateError::UnknownIssuer | CertificateError::BadSignature => format!(
                "the learner's certificate is not signed by the CA in --tls-ca ({}): give the CA that signed it",
                if matches!(c, CertificateError::UnknownIssuer) { "unknown issuer" } else { "bad signature" }
            ),
            CertificateError::Expired | CertificateError::ExpiredContext { .. } => {
                "the learner's certificate has expired: make a new one (`learner certs`) and send the learner SIGHUP".into()
            }
            CertificateError::NotValidYet | CertificateError::NotValidYetContext { .. } => {
                "the learner's certificate is not valid yet (its start date is in the future: check both machines' clocks)".into()
            }
            CertificateError::NotValidForName | CertificateError::NotValidForNameContext { .. } => format!(
                "hostname mismatch: the learner's certificate is not valid for `{host}`: connect with a name it lists, or \
                 make one that lists `{host}` (`learner certs --hosts {host},...`)"
            ),
            other => format!("the learner's certificate was refused: {other:?}"),
        },
        E::AlertReceived(AlertDescription::CertificateRequired) => {
            "the learner requires a client certificate (mutual TLS): give --tls-cert FILE and --tls-key FILE".into()
        }
        E::AlertReceived(
            a @ (AlertDescription::BadCertificate
            | AlertDescription::UnknownCA
            | AlertDescription::CertificateExpired
            | AlertDescription::CertificateUnknown
            | AlertDescription::DecryptError),
        ) => format!(
            "the learner refused this client's certificate ({a:?}): it must be signed by the CA the learner trusts \
             (its --tls-client-ca) and valid now"
        ),
        E::InvalidMessage(_) | E::InappropriateMessage { .. } | E::InappropriateHandshakeMessage { .. } => {
            format!("the server did not answer in TLS ({e}): it may serve plaintext (then connect with http:// and no --tls-ca)")
        }
        other => format!("TLS: {other}"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn attempt(tls: bool) -> Attempt<'static> {
        Attempt { tls, client_cert: false, host: "learner", connected: false }
    }

    /// A connection that ends under the first exchange is the other side speaking the other
    /// protocol, however the end is worded: an `UnexpectedEof` says "unexpected end of file".
    #[test]
    fn a_connection_ended_at_once_suggests_the_other_protocol_whatever_its_wording() {
        for kind in [std::io::ErrorKind::UnexpectedEof, std::io::ErrorKind::ConnectionReset, std::io::ErrorKind::BrokenPipe] {
            let err = std::io::Error::from(kind);
            let plain = describe(&err, &attempt(false));
            assert!(plain.contains("it may serve TLS"), "{kind:?}: {plain}");
            let tls = describe(&err, &attempt(true));
            assert!(tls.contains("it may serve plaintext"), "{kind:?}: {tls}");
        }
        let other = std::io::Error::other("something else entirely");
        assert_eq!(describe(&other, &attempt(false)), "something else entirely");
    }

    /// A learner that wants a client certificate closes the connection under the first request;
    /// the channel may say only that the connection was not ready (seen in CI under load).
    #[test]
    fn a_connection_lost_under_the_first_request_after_tls_is_the_client_certificate() {
        let err = std::io::Error::other("transport error: connection was not ready");
        let connected = |client_cert| Attempt { tls: true, client_cert, host: "learner", connected: true };
        let without = describe(&err, &connected(false));
        assert!(without.contains("requires a client certificate (mutual TLS)"), "{without}");
        let with = describe(&err, &connected(true));
        assert!(with.contains("the learner refused this client's certificate"), "{with}");
    }
}
