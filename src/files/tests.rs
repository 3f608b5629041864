use super::*;

#[test]
fn relative_paths_are_the_files_folders_and_absolute_ones_stay() {
    let cfg = Path::new("/etc/dronewatt/dronewatt.toml");
    assert_eq!(
        relative_to(cfg, Path::new("keys/pw")),
        Path::new("/etc/dronewatt/keys/pw")
    );
    assert_eq!(relative_to(cfg, Path::new("/abs/pw")), Path::new("/abs/pw"));
    // A config named without a folder: its folder is the working directory.
    assert_eq!(
        relative_to(Path::new("d.toml"), Path::new("pw")),
        Path::new("pw")
    );
    let mut field = Some(PathBuf::from("../m"));
    resolve(cfg, field.as_mut());
    assert_eq!(field.unwrap(), Path::new("/etc/dronewatt/../m"));
}

#[cfg(unix)]
#[test]
fn a_secret_readable_by_others_is_refused_naming_the_file_and_its_mode() {
    use std::os::unix::fs::PermissionsExt;
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("secret");
    std::fs::write(&p, "hunter2\n").unwrap();
    for mode in [0o644, 0o640, 0o604, 0o660, 0o610] {
        std::fs::set_permissions(&p, std::fs::Permissions::from_mode(mode)).unwrap();
        let e = read_private(&p).unwrap_err();
        assert!(e.contains(&format!("{mode:03o}")), "{e}");
        assert!(e.contains(&p.display().to_string()), "{e}");
    }
    std::fs::set_permissions(&p, std::fs::Permissions::from_mode(0o600)).unwrap();
    assert_eq!(read_private_text(&p).unwrap(), "hunter2\n");
    let e = read_private(&dir.path().join("none")).unwrap_err();
    assert!(e.contains("none"), "{e}");
}
