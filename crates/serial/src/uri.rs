//! Device URIs: `ps1a:///dev/ttyUSB0?addr=3&baud=9600`.

use std::collections::BTreeMap;
use std::str::FromStr;

/// A device named by scheme, port path and query parameters.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DeviceUri {
    /// Protocol / device family, e.g. `ps1a`.
    pub scheme: String,
    /// Port path (device node or pty link), e.g. `/dev/ttyUSB0`.
    pub path: String,
    /// Query parameters.
    pub params: BTreeMap<String, String>,
}

/// An invalid URI or parameter.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum UriError {
    /// Not a URI.
    #[error("invalid device URI {uri:?}: {reason} (expected e.g. ps1a:///dev/ttyUSB0?addr=3)")]
    Syntax {
        /// The text.
        uri: String,
        /// What is wrong.
        reason: String,
    },
    /// A parameter is missing.
    #[error("device URI {uri:?} lacks the parameter {name}")]
    Missing {
        /// The URI.
        uri: String,
        /// Parameter name.
        name: String,
    },
    /// A parameter has a bad value.
    #[error("device URI parameter {name}={value:?} is invalid: {reason}")]
    BadValue {
        /// Parameter name.
        name: String,
        /// Its text.
        value: String,
        /// What is wrong.
        reason: String,
    },
    /// A parameter is not known to the device family.
    #[error("unknown parameter {name:?} in device URI (known: {known})")]
    Unknown {
        /// Parameter name.
        name: String,
        /// Known names.
        known: String,
    },
}

impl FromStr for DeviceUri {
    type Err = UriError;
    fn from_str(s: &str) -> Result<Self, UriError> {
        let url =
            url::Url::parse(s).map_err(|e| UriError::Syntax { uri: s.into(), reason: e.to_string() })?;
        let mut path = url.path().to_string();
        if let Some(host) = url.host_str() {
            if !host.is_empty() {
                // `ps1a://dev/ttyUSB0` (two slashes): treat host as the first path segment.
                path = format!("/{host}{path}");
            }
        }
        if path.is_empty() || path == "/" {
            return Err(UriError::Syntax { uri: s.into(), reason: "no port path".into() });
        }
        let path = percent_decode(&path);
        let params = url.query_pairs().map(|(k, v)| (k.into_owned(), v.into_owned())).collect();
        Ok(DeviceUri { scheme: url.scheme().to_string(), path, params })
    }
}

fn percent_decode(s: &str) -> String {
    url::form_urlencoded::parse(format!("p={}", s.replace('+', "%2B")).as_bytes())
        .next()
        .map(|(_, v)| v.into_owned())
        .unwrap_or_else(|| s.to_string())
}

impl DeviceUri {
    /// A parameter parsed as `T`, or `None` if absent.
    pub fn get<T: FromStr>(&self, name: &str) -> Result<Option<T>, UriError>
    where
        T::Err: std::fmt::Display,
    {
        match self.params.get(name) {
            None => Ok(None),
            Some(v) => v.parse::<T>().map(Some).map_err(|e| UriError::BadValue {
                name: name.into(),
                value: v.clone(),
                reason: e.to_string(),
            }),
        }
    }

    /// Errors if a parameter outside `known` is present (typos must not pass silently).
    pub fn check_known(&self, known: &[&str]) -> Result<(), UriError> {
        for k in self.params.keys() {
            if !known.contains(&k.as_str()) {
                return Err(UriError::Unknown { name: k.clone(), known: known.join(", ") });
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::panic, clippy::unwrap_used)]
    use super::*;

    #[test]
    fn parses_the_issue_example() {
        let u: DeviceUri = "ps1a:///dev/ttyUSB0?addr=3&baud=9600".parse().unwrap();
        assert_eq!(u.scheme, "ps1a");
        assert_eq!(u.path, "/dev/ttyUSB0");
        assert_eq!(u.get::<u8>("addr").unwrap(), Some(3));
        assert_eq!(u.get::<u32>("baud").unwrap(), Some(9600));
        assert!(u.get::<u8>("baud").is_err());
        assert!(u.check_known(&["addr"]).is_err());
        let v: DeviceUri = "ps1a:///tmp/my%20line?addr=1".parse().unwrap();
        assert_eq!(v.path, "/tmp/my line");
    }
}
