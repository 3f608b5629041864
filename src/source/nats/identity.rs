//! Who sends to a vehicle, in a form the gateway can trust: the sender's NATS principal is
//! a token of the subject, and the server's per-user publish permissions are what make it
//! true.
//!
//! ```text
//!  dronewatt.to.<principal>.<instance>.<net>.<sys>
//! ```
//!
//! - **Principal**: the NATS user the worker logged in as (`--nats-user`), or the user's
//!   public key (the JWT's `sub`) with a `.creds` file; `anon` on an open loopback server.
//!   The server's config lets user `worker1` publish on `dronewatt.to.worker1.>` only
//!   (`config/nats-server.conf`), so a frame on `dronewatt.to.worker1.…` can only come
//!   from `worker1`'s credentials, whatever the sender claims elsewhere. A header, a reply
//!   inbox or a client name would be the sender's word, which a misbehaving worker can
//!   forge; NATS does not stamp the publisher on a message.
//! - **Instance**: `<pid>-<random>`, told apart among processes sharing one user (the same
//!   credentials: not a security boundary).
//! - A worker's lease entries hold `<principal>.<instance>`; the gateway forwards a frame
//!   only when the subject's `<principal>.<instance>` is the holder of the vehicle's
//!   partition at that moment (`src/cli/gateway.rs`).

use anyhow::{bail, Context as _, Result};
use base64::Engine as _;

use super::NatsArgs;

/// The principal of a client without credentials (an open loopback server).
pub const ANON: &str = "anon";

/// Whether `s` can be one subject token (and a lease holder's part): letters, digits,
/// `-` and `_`, 1 to 64 of them.
pub fn is_token(s: &str) -> bool {
    !s.is_empty()
        && s.len() <= 64
        && s.bytes()
            .all(|b| b.is_ascii_alphanumeric() || b == b'-' || b == b'_')
}

/// The principal this client logs in as: `--nats-user`, the `.creds` JWT's subject (the
/// user's public key), else [`ANON`]. A user name that cannot be a subject token is
/// refused, by name.
pub fn principal(a: &NatsArgs) -> Result<String> {
    if let Some(u) = &a.nats_user {
        if !is_token(u) {
            bail!(
                "--nats-user {u:?}: a fleet worker's NATS user must be letters, digits, '-' or \
                 '_' (it is a subject token: dronewatt.to.<user>.…)"
            );
        }
        return Ok(u.clone());
    }
    if let Some(f) = &a.nats_creds {
        let text = crate::files::read_private_text(f)
            .map_err(|e| anyhow::anyhow!("--nats-creds {}: {e}", f.display()))?;
        return jwt_subject(&text)
            .with_context(|| format!("--nats-creds {}: no user JWT subject", f.display()));
    }
    Ok(ANON.to_string())
}

/// The `sub` claim of the user JWT in a `.creds` file's text.
fn jwt_subject(creds: &str) -> Result<String> {
    let jwt = creds
        .lines()
        .skip_while(|l| !l.contains("BEGIN NATS USER JWT"))
        .nth(1)
        .map(str::trim)
        .context("no 'BEGIN NATS USER JWT' block")?;
    let payload = jwt.split('.').nth(1).context("the JWT has no payload")?;
    let bytes = base64::engine::general_purpose::URL_SAFE_NO_PAD
        .decode(payload.trim_end_matches('='))
        .context("the JWT's payload is not base64url")?;
    let v: serde_json::Value = serde_json::from_slice(&bytes).context("the JWT's payload")?;
    let sub = v["sub"].as_str().context("the JWT has no 'sub'")?;
    if !is_token(sub) {
        bail!("the JWT's subject {sub:?} is not a subject token");
    }
    Ok(sub.to_string())
}

/// This process's worker id: `<principal>.<pid>-<random>`.
pub fn worker_id(principal: &str) -> String {
    format!(
        "{principal}.{}-{:08x}",
        std::process::id(),
        rand::random::<u32>()
    )
}

/// The subject on which worker `worker` (`<principal>.<instance>`) sends to vehicle
/// (`net`, `sys`).
pub fn to_subject(worker: &str, net: u8, sys: u8) -> String {
    format!("{}.{worker}.{net}.{sys}", super::TO)
}

/// A downlink subject's sender (`<principal>.<instance>`) and vehicle, or `None` when it
/// is not one.
pub fn parse_to(subject: &str) -> Option<(String, u8, u8)> {
    let rest = subject.strip_prefix(super::TO)?.strip_prefix('.')?;
    let t: Vec<&str> = rest.split('.').collect();
    let [principal, instance, net, sys] = t.as_slice() else {
        return None;
    };
    if !is_token(principal) || !is_token(instance) {
        return None;
    }
    Some((
        format!("{principal}.{instance}"),
        net.parse().ok()?,
        sys.parse().ok()?,
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn downlink_subjects_name_their_sender_and_vehicle() {
        let w = worker_id("worker1");
        assert!(
            w.starts_with("worker1.") && w.split('.').count() == 2,
            "{w}"
        );
        let s = to_subject(&w, 2, 250);
        assert_eq!(parse_to(&s), Some((w, 2, 250)));
        for bad in [
            "dronewatt.to.0.3",
            "dronewatt.to.a.b.0.300",
            "dronewatt.to.a.b.c.0.3",
            "dronewatt.to.a..0.3",
            "dronewatt.tox.a.b.0.3",
            "dronewatt.to.*.b.0.3",
        ] {
            assert_eq!(parse_to(bad), None, "{bad}");
        }
    }

    #[test]
    fn a_user_that_is_no_subject_token_is_refused_and_creds_give_their_key() {
        let a = NatsArgs {
            nats_user: Some("ops.team".into()),
            ..Default::default()
        };
        assert!(principal(&a).unwrap_err().to_string().contains("ops.team"));
        assert_eq!(principal(&NatsArgs::default()).unwrap(), ANON);
        let claims = base64::engine::general_purpose::URL_SAFE_NO_PAD
            .encode(br#"{"sub":"UABC123","name":"worker one"}"#);
        let creds = format!(
            "-----BEGIN NATS USER JWT-----\neyJ0eXAiOiJKV1QifQ.{claims}.sig\n------END NATS USER \
             JWT------\n"
        );
        assert_eq!(jwt_subject(&creds).unwrap(), "UABC123");
        assert!(jwt_subject("no jwt here").is_err());
    }
}
