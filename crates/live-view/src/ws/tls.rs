//! TLS for a live view served beyond loopback (rustls, TLS 1.2 and 1.3 with the `ring`
//! provider): a certificate and key the user gives (PEM files), or a self-signed one made on
//! first use and kept in a directory of the user's own. A client pins the certificate by its
//! SHA-256 fingerprint, printed beside the token.
//!
//! Files are checked before they are read: regular files of at most [`MAX_PEM_BYTES`]; a key
//! readable or writable by anyone but its owner, or owned by another user, is refused (as
//! ssh refuses one); the directory of a made certificate is the user's and closed to others.
//! Nothing is overwritten: a directory holding only one of the two files is an error.

use rustls::pki_types::pem::PemObject;
use rustls::pki_types::{CertificateDer, PrivateKeyDer};
use sha2::{Digest, Sha256};
use std::fs::{DirBuilder, OpenOptions};
use std::io::{Read, Write};
use std::os::unix::fs::{DirBuilderExt, MetadataExt, OpenOptionsExt};
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// The largest certificate or key file read, bytes.
pub const MAX_PEM_BYTES: u64 = 1 << 20;

/// The certificate's file name in a directory of [`Tls::self_signed`].
pub const CERT_FILE: &str = "cert.pem";
/// The key's file name in a directory of [`Tls::self_signed`].
pub const KEY_FILE: &str = "key.pem";

/// Why a TLS identity cannot be used.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum TlsError {
    /// A file or directory could not be read, made or written.
    #[error("{path}: {source}")]
    Io {
        /// The path.
        path: PathBuf,
        /// The error.
        source: std::io::Error,
    },
    /// A file is not what it must be (its path, and what is wrong).
    #[error("{path}: {why}")]
    Refused {
        /// The path.
        path: PathBuf,
        /// What is wrong with it.
        why: String,
    },
    /// rustls refused the certificate and key together (a key that does not match, an
    /// unsupported algorithm).
    #[error("the certificate {cert} and key {key} cannot serve TLS: {why}")]
    Rejected {
        /// The certificate file.
        cert: PathBuf,
        /// The key file.
        key: PathBuf,
        /// rustls's reason.
        why: String,
    },
}

/// A TLS server identity: rustls's configuration and the certificate's fingerprint.
#[derive(Clone)]
pub struct Tls {
    pub(super) config: Arc<rustls::ServerConfig>,
    fingerprint: String,
}

impl std::fmt::Debug for Tls {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Tls")
            .field("fingerprint", &self.fingerprint)
            .finish_non_exhaustive()
    }
}

impl Tls {
    /// The certificate chain in `cert` (PEM, the server's certificate first) and its private
    /// key in `key` (PEM: PKCS#8, PKCS#1 or SEC1), checked as the module says.
    pub fn from_pem_files(cert: &Path, key: &Path) -> Result<Tls, TlsError> {
        let chain = certificates(cert, &read_checked(cert, false)?)?;
        let key_der = private_key(key, &read_checked(key, true)?)?;
        let fingerprint = fingerprint(&chain[0]);
        let rejected = |e: rustls::Error| TlsError::Rejected {
            cert: cert.to_owned(),
            key: key.to_owned(),
            why: e.to_string(),
        };
        let provider = Arc::new(rustls::crypto::ring::default_provider());
        let mut config = rustls::ServerConfig::builder_with_provider(provider)
            .with_safe_default_protocol_versions()
            .map_err(rejected)?
            .with_no_client_auth()
            .with_single_cert(chain, key_der)
            .map_err(rejected)?;
        // No TLS 1.3 session tickets: a view has a few long-lived clients, so resumption saves
        // nothing, and a ticket arriving while a client sends its upgrade request loses that
        // request in clients that read and write one TLS connection from two threads (Python's
        // `websockets.sync` client: about one connection in twenty stalled until the 5 s
        // handshake limit).
        config.send_tls13_tickets = 0;
        Ok(Tls {
            config: Arc::new(config),
            fingerprint,
        })
    }

    /// The self-signed identity kept in `dir` ([`CERT_FILE`], [`KEY_FILE`]), made there on
    /// first use (an ECDSA P-256 key; the certificate names `names`, e.g. the host's name and
    /// `localhost`) with the directory (mode 0700) and the key (0600) closed to other users.
    /// Returns it and whether it was made now.
    pub fn self_signed(dir: &Path, names: &[String]) -> Result<(Tls, bool), TlsError> {
        let io = |path: &Path| {
            let path = path.to_owned();
            move |source| TlsError::Io { path, source }
        };
        DirBuilder::new()
            .recursive(true)
            .mode(0o700)
            .create(dir)
            .map_err(io(dir))?;
        let meta = std::fs::symlink_metadata(dir).map_err(io(dir))?;
        let refused = |why: &str| TlsError::Refused {
            path: dir.to_owned(),
            why: why.to_owned(),
        };
        if !meta.is_dir() {
            return Err(refused("not a directory"));
        }
        if meta.uid() != own_uid() {
            return Err(refused("owned by another user"));
        }
        if meta.mode() & 0o022 != 0 {
            return Err(refused(
                "writable by other users, who could replace the key (chmod go-w)",
            ));
        }
        let (cert, key) = (dir.join(CERT_FILE), dir.join(KEY_FILE));
        let made = match (cert.exists(), key.exists()) {
            (true, true) => false,
            (false, false) => {
                let (cert_pem, key_pem) =
                    self_signed_pair(names).map_err(|e| TlsError::Refused {
                        path: cert.clone(),
                        why: format!("no self-signed certificate made: {e}"),
                    })?;
                write_new(&key, key_pem.as_bytes(), 0o600)?;
                write_new(&cert, cert_pem.as_bytes(), 0o644)?;
                true
            }
            (has_cert, _) => {
                let (present, missing) = if has_cert {
                    (&cert, &key)
                } else {
                    (&key, &cert)
                };
                return Err(TlsError::Refused {
                    path: missing.clone(),
                    why: format!(
                        "missing beside {} (remove both to have a new pair made)",
                        present.display()
                    ),
                });
            }
        };
        Ok((Tls::from_pem_files(&cert, &key)?, made))
    }

    /// The server certificate's SHA-256 fingerprint: 32 bytes as upper-case hex pairs joined by
    /// colons (as `openssl x509 -fingerprint -sha256` and Node's `fingerprint256` print it).
    pub fn fingerprint(&self) -> &str {
        &self.fingerprint
    }
}

/// A new self-signed certificate for `names` (subject `CN=fts-servo live view`) and its ECDSA
/// P-256 key, both PEM.
fn self_signed_pair(names: &[String]) -> Result<(String, String), rcgen::Error> {
    let mut params = rcgen::CertificateParams::new(names.to_vec())?;
    params
        .distinguished_name
        .push(rcgen::DnType::CommonName, "fts-servo live view");
    let key = rcgen::KeyPair::generate()?;
    let cert = params.self_signed(&key)?;
    Ok((cert.pem(), key.serialize_pem()))
}

/// The SHA-256 fingerprint of a certificate's DER bytes, `AB:CD:…`.
fn fingerprint(cert: &[u8]) -> String {
    Sha256::digest(cert)
        .iter()
        .map(|b| format!("{b:02X}"))
        .collect::<Vec<_>>()
        .join(":")
}

/// This process's effective user id (`u32::MAX`, which owns nothing, if unknown).
fn own_uid() -> u32 {
    super::peer::own_uid().unwrap_or(u32::MAX)
}

/// The bytes of `path`: a regular file of at most [`MAX_PEM_BYTES`]; a `secret` one owned by
/// this user and closed to others.
fn read_checked(path: &Path, secret: bool) -> Result<Vec<u8>, TlsError> {
    let refused = |why: String| TlsError::Refused {
        path: path.to_owned(),
        why,
    };
    let io = |source| TlsError::Io {
        path: path.to_owned(),
        source,
    };
    let (file, len) = daq_io::input_file::open_regular(path, MAX_PEM_BYTES).map_err(io)?;
    let meta = file.metadata().map_err(io)?;
    if secret && meta.uid() != own_uid() {
        return Err(refused("a private key owned by another user".into()));
    }
    if secret && meta.mode() & 0o077 != 0 {
        return Err(refused(format!(
            "a private key open to other users (mode {:o}; chmod 600)",
            meta.mode() & 0o777
        )));
    }
    let mut bytes = Vec::with_capacity(len as usize);
    file.take(MAX_PEM_BYTES)
        .read_to_end(&mut bytes)
        .map_err(io)?;
    Ok(bytes)
}

/// The certificates of a PEM file (at least one).
fn certificates(path: &Path, pem: &[u8]) -> Result<Vec<CertificateDer<'static>>, TlsError> {
    let chain = CertificateDer::pem_slice_iter(pem)
        .collect::<Result<Vec<_>, _>>()
        .map_err(|e| TlsError::Refused {
            path: path.to_owned(),
            why: format!("not PEM certificates: {e}"),
        })?;
    if chain.is_empty() {
        return Err(TlsError::Refused {
            path: path.to_owned(),
            why: "no certificate (-----BEGIN CERTIFICATE-----) in it".into(),
        });
    }
    Ok(chain)
}

/// The private key of a PEM file.
fn private_key(path: &Path, pem: &[u8]) -> Result<PrivateKeyDer<'static>, TlsError> {
    PrivateKeyDer::from_pem_slice(pem).map_err(|e| TlsError::Refused {
        path: path.to_owned(),
        why: format!("no PEM private key (PKCS#8, PKCS#1 or SEC1) in it: {e}"),
    })
}

/// Writes a new file (never one that exists) with `mode`.
fn write_new(path: &Path, bytes: &[u8], mode: u32) -> Result<(), TlsError> {
    let io = |source| TlsError::Io {
        path: path.to_owned(),
        source,
    };
    let mut file = OpenOptions::new()
        .write(true)
        .create_new(true)
        .mode(mode)
        .open(path)
        .map_err(io)?;
    file.write_all(bytes)
        .and_then(|()| file.sync_all())
        .map_err(io)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ws::{Front, FrontOptions};
    use rustls::client::danger::{HandshakeSignatureValid, ServerCertVerified, ServerCertVerifier};
    use rustls::client::{ClientSessionMemoryCache, ClientSessionStore, Resumption};
    use rustls::pki_types::{ServerName, UnixTime};
    use rustls::{DigitallySignedStruct, SignatureScheme};
    use std::net::TcpStream;
    use std::time::Duration;
    use tungstenite::client::IntoClientRequest;

    fn names() -> Vec<String> {
        vec!["localhost".into(), "127.0.0.1".into()]
    }

    fn mode(path: &Path) -> u32 {
        std::fs::metadata(path).unwrap().mode() & 0o777
    }

    /// Made once (key 0600, directory 0700), then kept: the same fingerprint, 32 hex pairs.
    #[test]
    fn a_self_signed_identity_is_made_once_and_kept() {
        let scratch = tempfile::tempdir().unwrap();
        let dir = scratch.path().join("fts-servo").join("live-view");
        let (first, made) = Tls::self_signed(&dir, &names()).unwrap();
        assert!(made);
        assert_eq!(mode(&dir.join(KEY_FILE)), 0o600);
        assert_eq!(mode(&dir), 0o700);
        let (again, made) = Tls::self_signed(&dir, &names()).unwrap();
        assert!(!made);
        assert_eq!(first.fingerprint(), again.fingerprint());
        let pairs: Vec<&str> = first.fingerprint().split(':').collect();
        assert_eq!(pairs.len(), 32);
        assert!(pairs
            .iter()
            .all(|p| p.len() == 2 && p.chars().all(|c| c.is_ascii_hexdigit())));
    }

    /// A key open to others, a directory others can write, half a pair (never completed over
    /// the half that is there) and a key of another certificate are refused, each naming why.
    #[test]
    fn unsafe_or_mismatched_files_are_refused() {
        use std::os::unix::fs::PermissionsExt;
        let scratch = tempfile::tempdir().unwrap();
        let (a, b) = (scratch.path().join("a"), scratch.path().join("b"));
        Tls::self_signed(&a, &names()).unwrap();
        Tls::self_signed(&b, &names()).unwrap();
        let chmod = |p: &Path, m: u32| {
            std::fs::set_permissions(p, std::fs::Permissions::from_mode(m)).unwrap()
        };
        let key = a.join(KEY_FILE);
        chmod(&key, 0o644);
        let err = Tls::from_pem_files(&a.join(CERT_FILE), &key).unwrap_err();
        assert!(err.to_string().contains("chmod 600"), "{err}");
        chmod(&key, 0o600);
        chmod(&a, 0o777);
        let err = Tls::self_signed(&a, &names()).unwrap_err();
        assert!(err.to_string().contains("writable by other users"), "{err}");
        chmod(&a, 0o700);
        std::fs::remove_file(a.join(CERT_FILE)).unwrap();
        let before = std::fs::read(&key).unwrap();
        let err = Tls::self_signed(&a, &names()).unwrap_err();
        assert!(err.to_string().contains("missing beside"), "{err}");
        assert_eq!(std::fs::read(&key).unwrap(), before);
        let err = Tls::from_pem_files(&b.join(CERT_FILE), &key).unwrap_err();
        assert!(matches!(err, TlsError::Rejected { .. }), "{err}");
        let err = Tls::from_pem_files(&b.join(KEY_FILE), &b.join(KEY_FILE)).unwrap_err();
        assert!(err.to_string().contains("no certificate"), "{err}");
    }

    /// A client that accepts exactly one certificate: the one with this fingerprint.
    #[derive(Debug)]
    struct Pinned {
        fingerprint: String,
        provider: Arc<rustls::crypto::CryptoProvider>,
    }

    impl ServerCertVerifier for Pinned {
        fn verify_server_cert(
            &self,
            end_entity: &CertificateDer<'_>,
            _intermediates: &[CertificateDer<'_>],
            _server_name: &ServerName<'_>,
            _ocsp_response: &[u8],
            _now: UnixTime,
        ) -> Result<ServerCertVerified, rustls::Error> {
            if fingerprint(end_entity) == self.fingerprint {
                Ok(ServerCertVerified::assertion())
            } else {
                Err(rustls::Error::General("not the pinned certificate".into()))
            }
        }

        fn verify_tls12_signature(
            &self,
            message: &[u8],
            cert: &CertificateDer<'_>,
            dss: &DigitallySignedStruct,
        ) -> Result<HandshakeSignatureValid, rustls::Error> {
            let algorithms = &self.provider.signature_verification_algorithms;
            rustls::crypto::verify_tls12_signature(message, cert, dss, algorithms)
        }

        fn verify_tls13_signature(
            &self,
            message: &[u8],
            cert: &CertificateDer<'_>,
            dss: &DigitallySignedStruct,
        ) -> Result<HandshakeSignatureValid, rustls::Error> {
            let algorithms = &self.provider.signature_verification_algorithms;
            rustls::crypto::verify_tls13_signature(message, cert, dss, algorithms)
        }

        fn supported_verify_schemes(&self) -> Vec<SignatureScheme> {
            self.provider
                .signature_verification_algorithms
                .supported_schemes()
        }
    }

    type Secure = rustls::StreamOwned<rustls::ClientConnection, TcpStream>;

    /// A WebSocket client over TLS pinned to `pin`, with `token`, to the front on `port`.
    fn connect(
        port: u16,
        pin: &str,
        token: &str,
    ) -> tungstenite::Result<tungstenite::WebSocket<Secure>> {
        connect_keeping_tickets(port, pin, token, Arc::new(ClientSessionMemoryCache::new(8)))
    }

    /// [`connect`], keeping the session tickets the server sends in `tickets`.
    fn connect_keeping_tickets(
        port: u16,
        pin: &str,
        token: &str,
        tickets: Arc<ClientSessionMemoryCache>,
    ) -> tungstenite::Result<tungstenite::WebSocket<Secure>> {
        let provider = Arc::new(rustls::crypto::ring::default_provider());
        let verifier = Arc::new(Pinned {
            fingerprint: pin.to_owned(),
            provider: provider.clone(),
        });
        let mut config = rustls::ClientConfig::builder_with_provider(provider)
            .with_safe_default_protocol_versions()
            .unwrap()
            .dangerous()
            .with_custom_certificate_verifier(verifier)
            .with_no_client_auth();
        config.resumption = Resumption::store(tickets);
        let name = ServerName::try_from("localhost").unwrap();
        let connection = rustls::ClientConnection::new(Arc::new(config), name).unwrap();
        let tcp = TcpStream::connect(("127.0.0.1", port))?;
        tcp.set_read_timeout(Some(Duration::from_secs(30)))?;
        let mut req = format!("wss://localhost:{port}/?token={token}")
            .into_client_request()
            .unwrap();
        req.headers_mut().insert(
            "sec-websocket-protocol",
            "foxglove.websocket.v1".parse().unwrap(),
        );
        let stream = rustls::StreamOwned::new(connection, tcp);
        tungstenite::client(req, stream)
            .map(|(ws, _)| ws)
            .map_err(|e| match e {
                tungstenite::HandshakeError::Failure(f) => f,
                tungstenite::HandshakeError::Interrupted(_) => tungstenite::Error::ConnectionClosed,
            })
    }

    /// A front with an identity: a client pinned to its fingerprint with the token reads the
    /// server's info over TLS and was sent no session ticket; the wrong token is refused (401,
    /// inside TLS); a client pinned to another certificate does not get through the TLS
    /// handshake; a cleartext WebSocket client gets no handshake.
    #[test]
    fn a_tls_front_serves_only_the_pinned_certificate_and_the_token() {
        let scratch = tempfile::tempdir().unwrap();
        let (tls, _) = Tls::self_signed(scratch.path(), &names()).unwrap();
        let pin = tls.fingerprint().to_owned();
        let (asks, _requests) = std::sync::mpsc::channel();
        let front = Front::start(
            FrontOptions {
                name: "tls test".into(),
                host: "127.0.0.1".into(),
                port: 0,
                metadata: Default::default(),
                channels: vec![],
                service: None,
                read_only: true,
                token: Some("secret".into()),
                tls: Some(tls),
            },
            asks,
        )
        .unwrap();
        let port = front.port();
        let tickets = Arc::new(ClientSessionMemoryCache::new(8));
        let mut ws = connect_keeping_tickets(port, &pin, "secret", tickets.clone()).unwrap();
        match ws.read().unwrap() {
            tungstenite::Message::Text(t) => assert!(t.contains("serverInfo"), "{t}"),
            other => panic!("{other:?}"),
        }
        drop(ws);
        // No session tickets (they precede the upgrade's answer, so they would be here):
        // see `Tls::from_pem_files`.
        let localhost = ServerName::try_from("localhost").unwrap();
        assert!(tickets.take_tls13_ticket(&localhost).is_none());
        match connect(port, &pin, "guess") {
            Err(tungstenite::Error::Http(r)) => assert_eq!(r.status(), 401),
            other => panic!("a wrong token: {:?}", other.map(|_| ())),
        }
        let other = "00:".repeat(31) + "00";
        assert!(connect(port, &other, "secret").is_err());
        let mut req = format!("ws://127.0.0.1:{port}/?token=secret")
            .into_client_request()
            .unwrap();
        req.headers_mut().insert(
            "sec-websocket-protocol",
            "foxglove.websocket.v1".parse().unwrap(),
        );
        let tcp = TcpStream::connect(("127.0.0.1", port)).unwrap();
        tcp.set_read_timeout(Some(Duration::from_secs(30))).unwrap();
        assert!(tungstenite::client(req, tcp).is_err());
        front.stop();
    }
}
