//! Token authentication of gRPC calls: with `--auth-token-file`, every call must carry
//! `authorization: Bearer TOKEN`. The scheme is matched without regard to case (RFC 7235 §2.1:
//! `bearer` is `Bearer`), and the token is compared in constant time (`subtle`), so that the time
//! a refusal takes tells nothing about how much of a guess was right.

use subtle::{Choice, ConstantTimeEq};
use tonic::{Request, Status};

/// The interceptor of `learner serve`: lets every call through without a token, else only the
/// calls that carry it.
#[allow(clippy::result_large_err)]
pub fn interceptor(token: Option<String>) -> impl Fn(Request<()>) -> Result<Request<()>, Status> + Clone {
    move |req: Request<()>| {
        let Some(expected) = &token else { return Ok(req) };
        let header = req.metadata().get("authorization").map(|v| v.to_str().unwrap_or("\u{fffd}"));
        check(expected, header)?;
        Ok(req)
    }
}

/// Checks an `authorization` header value against the expected token.
#[allow(clippy::result_large_err)]
pub fn check(expected: &str, header: Option<&str>) -> Result<(), Status> {
    let Some(value) = header else {
        return Err(Status::unauthenticated("this learner requires an auth token: send `authorization: Bearer TOKEN`"));
    };
    let (scheme, presented) = value.trim().split_once(char::is_whitespace).unwrap_or((value.trim(), ""));
    if !scheme.eq_ignore_ascii_case("bearer") {
        return Err(Status::unauthenticated(format!(
            "authorization scheme `{}` is not supported: send `authorization: Bearer TOKEN`",
            scheme.chars().take(16).collect::<String>()
        )));
    }
    if bool::from(tokens_equal(presented.trim().as_bytes(), expected.as_bytes())) {
        Ok(())
    } else {
        Err(Status::unauthenticated("wrong auth token"))
    }
}

/// Whether two tokens are equal, in a time that depends only on the presented token's length
/// (which its sender knows): every byte is compared, whether or not an earlier one differed, and
/// the lengths are compared the same way.
fn tokens_equal(presented: &[u8], expected: &[u8]) -> Choice {
    let same_length = (presented.len() as u64).ct_eq(&(expected.len() as u64));
    let mut same_bytes = Choice::from(1);
    for (i, &b) in presented.iter().enumerate() {
        // Past the expected token's end, compare against its bytes again: the length check has
        // already failed, and the loop keeps its shape.
        let e = if expected.is_empty() { 0 } else { expected[i % expected.len()] };
        same_bytes &= b.ct_eq(&e);
    }
    same_length & same_bytes
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ok(header: &str) -> bool {
        check("s3cret", Some(header)).is_ok()
    }

    #[test]
    fn the_scheme_is_case_insensitive_and_the_token_exact() {
        for accepted in ["Bearer s3cret", "bearer s3cret", "BEARER s3cret", "bEaReR   s3cret", " Bearer s3cret "] {
            assert!(ok(accepted), "{accepted:?} refused");
        }
        for refused in ["Bearer s3cre", "Bearer s3cret2", "Bearer S3CRET", "Bearer", "Bearer ", "s3cret", "Basic s3cret", "Bearers3cret"] {
            assert!(!ok(refused), "{refused:?} accepted");
        }
    }

    #[test]
    fn refusals_say_what_to_send() {
        let missing = check("s3cret", None).unwrap_err();
        assert_eq!(missing.code(), tonic::Code::Unauthenticated);
        assert!(missing.message().contains("Bearer TOKEN"), "{}", missing.message());
        let basic = check("s3cret", Some("Basic dXNlcjpwYXNz")).unwrap_err();
        assert!(basic.message().contains("`Basic` is not supported"), "{}", basic.message());
        assert_eq!(check("s3cret", Some("Bearer nope")).unwrap_err().message(), "wrong auth token");
    }

    #[test]
    fn token_comparison_covers_every_length_case() {
        assert!(bool::from(tokens_equal(b"abc", b"abc")));
        assert!(!bool::from(tokens_equal(b"abd", b"abc")));
        assert!(!bool::from(tokens_equal(b"ab", b"abc")));
        assert!(!bool::from(tokens_equal(b"abcabc", b"abc")), "a repeat of the token must not pass");
        assert!(!bool::from(tokens_equal(b"", b"abc")));
        assert!(!bool::from(tokens_equal(b"a", b"")));
    }

    #[test]
    fn the_interceptor_passes_everything_without_a_token_and_checks_metadata_with_one() {
        let open = interceptor(None);
        assert!(open(Request::new(())).is_ok());
        let guarded = interceptor(Some("s3cret".into()));
        assert!(guarded(Request::new(())).is_err());
        let mut req = Request::new(());
        req.metadata_mut().insert("authorization", "bearer s3cret".parse().unwrap());
        assert!(guarded(req).is_ok());
    }
}
