//! `motus user add | passwd | role | del | list`: offline user management.

use std::sync::Arc;
use std::time::SystemTime;

use anyhow::{bail, Context, Result};
use motus_lab::{PasswordPolicy, Role, SqliteStore, Store, UnixMs, Users};
use serde_json::json;

use crate::cli_station::{RoleArg, UserAction, UserArgs};

fn role(r: RoleArg) -> Role {
    match r {
        RoleArg::Viewer => Role::Viewer,
        RoleArg::Student => Role::Student,
        RoleArg::Admin => Role::Admin,
    }
}

fn read_password() -> Result<String> {
    let mut line = String::new();
    std::io::stdin().read_line(&mut line).context("cannot read the password from standard input")?;
    let pw = line.trim_end_matches(['\n', '\r']).to_owned();
    if pw.is_empty() {
        bail!("no password on standard input (e.g. `echo 'a long passphrase' | motus user add alice`)");
    }
    Ok(pw)
}

/// Runs a `user` command.
pub fn run(a: UserArgs) -> Result<()> {
    let path = match (&a.db, &a.config) {
        (Some(db), _) => db.clone(),
        (None, Some(cfg)) => {
            // The station's database sits beside its cell file: a mistyped path must not
            // create a database no station reads.
            if !cfg.is_file() {
                bail!(
                    "cell file {} not found: give the cell file `motus serve --config` reads (its users are kept in {}), or --db <file>",
                    cfg.display(),
                    motus_lab::store::default_db_path(cfg).display()
                );
            }
            motus_lab::store::default_db_path(cfg)
        }
        (None, None) => bail!("give --db <file> or --config <cell.toml>"),
    };
    let store: Arc<dyn Store> =
        Arc::new(SqliteStore::open(&path).with_context(|| format!("cannot open {}", path.display()))?);
    let users = Users::new(store, PasswordPolicy::default());
    let now = UnixMs::from(SystemTime::now());
    match a.action {
        UserAction::Add { name, role: r } => {
            let u = users.add(&name, &read_password()?, role(r), now)?;
            println!("{}", json!({ "added": u.name, "role": u.role.as_str() }));
        }
        UserAction::Passwd { name } => {
            users.passwd(&name, &read_password()?, now)?;
            println!("{}", json!({ "password_changed": name }));
        }
        UserAction::Role { name, role: r } => {
            let u = users.set_role(&name, role(r), now)?;
            println!("{}", json!({ "user": u.name, "role": u.role.as_str() }));
        }
        UserAction::Del { name } => {
            users.delete(&name)?;
            println!("{}", json!({ "deleted": name }));
        }
        UserAction::List => {
            for u in users.list()? {
                println!("{}", json!({ "user": u.name, "role": u.role.as_str() }));
            }
        }
    }
    Ok(())
}
