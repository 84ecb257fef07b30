//! Who may speak on a gateway's Zenoh network. The gateway is a small
//! certificate authority: each cell, and each ROS 2 machine let onto the
//! network, holds a certificate it issued, named for it (`ZenohCredentials`,
//! one file to hand over). The gateway's router asks every connection for
//! one (mutual TLS, Zenoh's own) and lets each member put, declare and
//! query only its own keys (Zenoh's access control, built here from the
//! members the gateway issued to): a stranger cannot join, a cell cannot
//! speak for another, and a member taken off the list gets nothing.
//!
//! The folder (`vl gateway --keys`) holds `authority.pem` (the authority's
//! certificate and key, readable by its owner only) and `members.toml`
//! (whom it issued to). The router's own certificate is made anew at each
//! start, signed by the authority, for the names cells reach it by.

use std::path::{Path, PathBuf};

use rcgen::{
    BasicConstraints, CertificateParams, DnType, ExtendedKeyUsagePurpose, IsCa, Issuer, KeyPair,
    KeyUsagePurpose,
};
use serde::{Deserialize, Serialize};
use serde_json::{Value, json};
use vl_core::CellName;

use super::keys;

/// The authority's certificate and key, in one file.
const AUTHORITY: &str = "authority.pem";
/// Whom the authority issued to.
const MEMBERS: &str = "members.toml";
/// The authority's name in every certificate it signs.
const AUTHORITY_NAME: &str = "vl gateway authority";

/// Why the gateway's authority or a member's credentials cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum TrustError {
    #[error("cannot read {path}: {why}")]
    Read { path: PathBuf, why: String },
    #[error("cannot write {path}: {why}")]
    Write { path: PathBuf, why: std::io::Error },
    #[error("{path} holds no {what}")]
    Missing { path: PathBuf, what: &'static str },
    #[error("cannot make a certificate: {0}")]
    Certificate(#[from] rcgen::Error),
    #[error("{0} is not a member of this gateway")]
    NotAMember(ZenohMember),
}

/// One who may join a gateway's network.
#[derive(Debug, Clone, PartialEq, Eq, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", tag = "kind", content = "name")]
pub enum ZenohMember {
    /// A cell: its own keys `vl/cells/NAME/**`, and its ROS 2 side's.
    Cell(CellName),
    /// A ROS 2 machine (rviz, a teleop, a robot's base): ROS 2's keys, none
    /// of the lab's own.
    Ros2(CellName),
}

impl ZenohMember {
    /// The certificate's common name, which Zenoh's access control matches.
    fn common_name(&self) -> String {
        match self {
            ZenohMember::Cell(name) => format!("cell:{name}"),
            ZenohMember::Ros2(name) => format!("ros2:{name}"),
        }
    }
}

impl std::fmt::Display for ZenohMember {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ZenohMember::Cell(name) => write!(f, "cell {name}"),
            ZenohMember::Ros2(name) => write!(f, "ROS 2 machine {name}"),
        }
    }
}

/// What a member presents: its certificate and key, and the authority it
/// trusts the gateway by. Kept as one TOML file (its key: owner only).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct ZenohCredentials {
    #[serde(flatten)]
    pub member: ZenohMember,
    authority: String,
    certificate: String,
    key: String,
}

impl ZenohCredentials {
    /// Reads credentials a gateway issued.
    pub fn load(path: &Path) -> Result<ZenohCredentials, TrustError> {
        let read = |why: String| TrustError::Read {
            path: path.to_owned(),
            why,
        };
        let text = std::fs::read_to_string(path).map_err(|e| read(e.to_string()))?;
        let credentials: ZenohCredentials =
            toml::from_str(&text).map_err(|e| read(e.to_string()))?;
        // Refused here, not deep in a TLS handshake that retries forever.
        KeyPair::from_pem(&credentials.key).map_err(|e| read(format!("its key: {e}")))?;
        for (what, pem) in [
            ("authority", &credentials.authority),
            ("certificate", &credentials.certificate),
        ] {
            use rustls::pki_types::CertificateDer;
            use rustls::pki_types::pem::PemObject;
            CertificateDer::from_pem_slice(pem.as_bytes())
                .map_err(|e| read(format!("its {what}: {e}")))?;
        }
        Ok(credentials)
    }

    /// Writes them to `path`, readable by its owner only.
    pub fn save(&self, path: &Path) -> Result<(), TrustError> {
        let text = format!(
            "# vl: credentials of {} on a gateway's Zenoh network. They hold its\n\
             # private key: keep this file on that machine only.\n{}",
            self.member,
            toml::to_string(self).unwrap_or_default()
        );
        vl_host::write_private(path, text.as_bytes()).map_err(|why| TrustError::Write {
            path: path.to_owned(),
            why,
        })
    }
}

/// A gateway's authority, kept in its folder.
pub struct ZenohAuthority {
    dir: PathBuf,
    certificate: String,
    issuer: Issuer<'static, KeyPair>,
}

/// The authority's own certificate's parameters: the same at every start,
/// so what it signs names the certificate it keeps.
fn authority_params() -> Result<CertificateParams, rcgen::Error> {
    let mut params = CertificateParams::new(Vec::new())?;
    params.is_ca = IsCa::Ca(BasicConstraints::Constrained(0));
    params.key_usages = vec![
        KeyUsagePurpose::KeyCertSign,
        KeyUsagePurpose::CrlSign,
        KeyUsagePurpose::DigitalSignature,
    ];
    params
        .distinguished_name
        .push(DnType::CommonName, AUTHORITY_NAME);
    Ok(params)
}

#[derive(Default, Serialize, Deserialize)]
struct Members {
    #[serde(default, rename = "member")]
    members: Vec<ZenohMember>,
}

impl ZenohAuthority {
    /// The authority kept in `dir`, made there the first time.
    pub fn open(dir: &Path) -> Result<ZenohAuthority, TrustError> {
        let path = dir.join(AUTHORITY);
        if !path.exists() {
            let mut folder = std::fs::DirBuilder::new();
            folder.recursive(true);
            #[cfg(unix)]
            std::os::unix::fs::DirBuilderExt::mode(&mut folder, 0o700);
            folder.create(dir).map_err(|why| TrustError::Write {
                path: dir.to_owned(),
                why,
            })?;
            let key = KeyPair::generate()?;
            let certificate = authority_params()?.self_signed(&key)?;
            let pem = format!("{}{}", certificate.pem(), key.serialize_pem());
            vl_host::write_private(&path, pem.as_bytes()).map_err(|why| TrustError::Write {
                path: path.clone(),
                why,
            })?;
        }
        let text = std::fs::read_to_string(&path).map_err(|e| TrustError::Read {
            path: path.clone(),
            why: e.to_string(),
        })?;
        let certificate = pem_block(&text, "CERTIFICATE").ok_or(TrustError::Missing {
            path: path.clone(),
            what: "certificate",
        })?;
        let key_pem = pem_block(&text, "PRIVATE KEY").ok_or(TrustError::Missing {
            path: path.clone(),
            what: "private key",
        })?;
        let key = KeyPair::from_pem(&key_pem).map_err(|e| TrustError::Read {
            path,
            why: e.to_string(),
        })?;
        Ok(ZenohAuthority {
            dir: dir.to_owned(),
            certificate,
            issuer: Issuer::new(authority_params()?, key),
        })
    }

    /// Whom it issued to and did not revoke.
    pub fn members(&self) -> Result<Vec<ZenohMember>, TrustError> {
        let path = self.dir.join(MEMBERS);
        match std::fs::read_to_string(&path) {
            Ok(text) => toml::from_str::<Members>(&text)
                .map(|m| m.members)
                .map_err(|e| TrustError::Read {
                    path,
                    why: e.to_string(),
                }),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(Vec::new()),
            Err(e) => Err(TrustError::Read {
                path,
                why: e.to_string(),
            }),
        }
    }

    fn keep_members(&self, mut members: Vec<ZenohMember>) -> Result<(), TrustError> {
        members.sort();
        members.dedup();
        let text = toml::to_string(&Members { members }).unwrap_or_default();
        let path = self.dir.join(MEMBERS);
        vl_host::write_private(&path, text.as_bytes())
            .map_err(|why| TrustError::Write { path, why })
    }

    /// New credentials for `member`, who is a member from the gateway's
    /// next start.
    pub fn issue(&self, member: ZenohMember) -> Result<ZenohCredentials, TrustError> {
        let mut params = CertificateParams::new(Vec::new())?;
        params
            .distinguished_name
            .push(DnType::CommonName, member.common_name());
        params.extended_key_usages = vec![ExtendedKeyUsagePurpose::ClientAuth];
        params.key_usages = vec![KeyUsagePurpose::DigitalSignature];
        let key = KeyPair::generate()?;
        let certificate = params.signed_by(&key, &self.issuer)?;
        let mut members = self.members()?;
        members.push(member.clone());
        self.keep_members(members)?;
        Ok(ZenohCredentials {
            member,
            authority: self.certificate.clone(),
            certificate: certificate.pem(),
            key: key.serialize_pem(),
        })
    }

    /// Takes `member` off the list: from the gateway's next start its
    /// certificate still connects but may do nothing.
    pub fn revoke(&self, member: &ZenohMember) -> Result<(), TrustError> {
        let mut members = self.members()?;
        let before = members.len();
        members.retain(|m| m != member);
        if members.len() == before {
            return Err(TrustError::NotAMember(member.clone()));
        }
        self.keep_members(members)
    }

    /// What the gateway's router listens with: a certificate for `names`
    /// (the host names and addresses cells reach it by), signed now, and
    /// the access control for the members.
    pub fn router(&self, names: Vec<String>, ros2_domain: u32) -> Result<RouterTrust, TrustError> {
        let mut params = CertificateParams::new(names)?;
        params
            .distinguished_name
            .push(DnType::CommonName, "vl gateway");
        params.extended_key_usages = vec![ExtendedKeyUsagePurpose::ServerAuth];
        params.key_usages = vec![KeyUsagePurpose::DigitalSignature];
        let key = KeyPair::generate()?;
        let certificate = params.signed_by(&key, &self.issuer)?;
        Ok(RouterTrust {
            authority: self.certificate.clone(),
            certificate: certificate.pem(),
            key: key.serialize_pem(),
            members: self.members()?,
            ros2_domain,
        })
    }
}

/// The first PEM block labelled `label` in `text`, whole.
fn pem_block(text: &str, label: &str) -> Option<String> {
    let begin = format!("-----BEGIN {label}-----");
    let end = format!("-----END {label}-----");
    let from = text.find(&begin)?;
    let to = text[from..].find(&end)? + from + end.len();
    Some(format!("{}\n", &text[from..to]))
}

/// A gateway router's side of the trust: its certificate, the authority
/// it asks members' certificates of, and what each member may do.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RouterTrust {
    authority: String,
    certificate: String,
    key: String,
    members: Vec<ZenohMember>,
    ros2_domain: u32,
}

impl RouterTrust {
    /// Whether `name` is a cell the authority issued to.
    pub(crate) fn is_cell(&self, name: &CellName) -> bool {
        self.members
            .iter()
            .any(|m| matches!(m, ZenohMember::Cell(cell) if cell == name))
    }

    /// Zenoh's `access_control`: nothing unless a rule allows it. A cell
    /// puts, declares and answers on its own keys, and hears what the
    /// gateway sends there; its ROS 2 side speaks in its own namespace. A
    /// ROS 2 machine speaks ROS 2 anywhere but never on the lab's keys.
    pub(crate) fn access_control(&self) -> Value {
        const ALL: [&str; 9] = [
            "put",
            "delete",
            "declare_subscriber",
            "query",
            "declare_queryable",
            "reply",
            "liveliness_token",
            "declare_liveliness_subscriber",
            "liveliness_query",
        ];
        const LIVELINESS: [&str; 3] = [
            "liveliness_token",
            "declare_liveliness_subscriber",
            "liveliness_query",
        ];
        const BOTH: [&str; 2] = ["ingress", "egress"];
        let domain = self.ros2_domain;
        let ros2_tokens = format!("@ros2_lv/{domain}/**");
        // `**` matches no chunk that begins with `@` (zenoh-ext's `@adv`
        // caches, rmw_zenoh's `@ros2_lv` tokens): those are named.
        let anywhere = ["**", "**/@adv/**"];
        let mut rules = vec![
            // A publisher sends only where it hears of a subscriber: the
            // keys members' subscriptions are on are told to every member.
            json!({"id": "hear-subscribers", "permission": "allow", "flows": ["egress"],
                   "messages": ["declare_subscriber"], "key_exprs": anywhere}),
            json!({"id": "ros2-liveliness", "permission": "allow", "flows": BOTH,
                   "messages": LIVELINESS, "key_exprs": [ros2_tokens]}),
            json!({"id": "ros2-any", "permission": "allow", "flows": BOTH, "messages": ALL,
                   "key_exprs": anywhere}),
            json!({"id": "not-the-lab-s", "permission": "deny", "flows": BOTH, "messages": ALL,
                   "key_exprs": ["vl/**"]}),
        ];
        let mut subjects = Vec::new();
        let mut policies = Vec::new();
        let mut ros2 = Vec::new();
        for (n, member) in self.members.iter().enumerate() {
            let subject = format!("member-{n}");
            subjects.push(json!({"id": subject, "cert_common_names": [member.common_name()]}));
            match member {
                ZenohMember::Cell(name) => {
                    let own = format!("{}/**", keys::cell(name));
                    let own_ros2 = format!("{domain}/{name}/**");
                    let own_caches = format!("{domain}/{name}/**/@adv/**");
                    let rule = format!("cell-{name}");
                    rules.push(json!({
                        "id": rule, "permission": "allow", "flows": BOTH, "messages": ALL,
                        "key_exprs": [own, own_ros2, own_caches],
                    }));
                    policies.push(json!({
                        "rules": [rule, "hear-subscribers", "ros2-liveliness"],
                        "subjects": [subject],
                    }));
                }
                ZenohMember::Ros2(_) => ros2.push(subject),
            }
        }
        if !ros2.is_empty() {
            policies.push(
                json!({"rules": ["ros2-any", "ros2-liveliness", "not-the-lab-s"],
                                 "subjects": ros2}),
            );
        }
        json!({
            "enabled": true,
            "default_permission": "deny",
            "rules": rules,
            "subjects": subjects,
            "policies": policies,
        })
    }

    /// Zenoh's TLS settings for the router: its certificate, and every
    /// connection's asked for and checked against the authority.
    pub(crate) fn tls(&self) -> Value {
        json!({
            "root_ca_certificate_base64": base64_of(&self.authority),
            "listen_certificate_base64": base64_of(&self.certificate),
            "listen_private_key_base64": base64_of(&self.key),
            "enable_mtls": true,
            "verify_name_on_connect": true,
        })
    }
}

impl ZenohCredentials {
    /// Zenoh's TLS settings for a member connecting: its certificate, and
    /// the gateway's checked against the authority and the name it is
    /// reached by.
    pub(crate) fn tls(&self) -> Value {
        json!({
            "root_ca_certificate_base64": base64_of(&self.authority),
            "connect_certificate_base64": base64_of(&self.certificate),
            "connect_private_key_base64": base64_of(&self.key),
            "enable_mtls": true,
            "verify_name_on_connect": true,
        })
    }
}

fn base64_of(pem: &str) -> String {
    use base64::Engine;
    base64::engine::general_purpose::STANDARD.encode(pem)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dir(tag: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("vl-trust-{tag}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        dir
    }

    #[test]
    fn an_authority_keeps_its_members_and_its_certificate() {
        let dir = dir("keeps");
        let first = ZenohAuthority::open(&dir).unwrap();
        let a = ZenohMember::Cell("a".parse().unwrap());
        let tool = ZenohMember::Ros2("rviz".parse().unwrap());
        let issued = first.issue(a.clone()).unwrap();
        first.issue(tool.clone()).unwrap();
        let again = ZenohAuthority::open(&dir).unwrap();
        assert_eq!(again.certificate, first.certificate);
        assert_eq!(again.members().unwrap(), vec![a.clone(), tool.clone()]);
        let file = dir.join("a.toml");
        issued.save(&file).unwrap();
        assert_eq!(ZenohCredentials::load(&file).unwrap(), issued);
        again.revoke(&a).unwrap();
        assert_eq!(again.members().unwrap(), vec![tool]);
        assert!(matches!(again.revoke(&a), Err(TrustError::NotAMember(_))));
        #[cfg(unix)]
        for kept in [dir.join(AUTHORITY), file] {
            use std::os::unix::fs::PermissionsExt;
            let mode = std::fs::metadata(&kept).unwrap().permissions().mode();
            assert_eq!(mode & 0o077, 0, "{}: {mode:o}", kept.display());
        }
        let _ = std::fs::remove_dir_all(dir);
    }

    #[test]
    fn each_cell_may_use_its_own_keys_only() {
        let dir = dir("acl");
        let authority = ZenohAuthority::open(&dir).unwrap();
        for name in ["a", "b"] {
            authority
                .issue(ZenohMember::Cell(name.parse().unwrap()))
                .unwrap();
        }
        let acl = authority
            .router(vec!["localhost".into()], 0)
            .unwrap()
            .access_control();
        assert_eq!(acl["default_permission"], "deny");
        let rule = |id: &str| {
            acl["rules"]
                .as_array()
                .unwrap()
                .iter()
                .find(|r| r["id"] == id)
                .cloned()
                .unwrap()
        };
        assert_eq!(
            rule("cell-a")["key_exprs"],
            json!(["vl/cells/a/**", "0/a/**", "0/a/**/@adv/**"])
        );
        assert_eq!(acl["subjects"][1]["cert_common_names"], json!(["cell:b"]));
        let _ = std::fs::remove_dir_all(dir);
    }

    #[test]
    fn credentials_that_do_not_read_say_so() {
        let dir = dir("bad");
        std::fs::create_dir_all(&dir).unwrap();
        let file = dir.join("x.toml");
        std::fs::write(&file, "kind = \"cell\"\nname = \"a\"\n").unwrap();
        let e = ZenohCredentials::load(&file).unwrap_err().to_string();
        assert!(e.contains("x.toml"), "{e}");
        let _ = std::fs::remove_dir_all(dir);
    }
}
