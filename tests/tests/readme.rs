//! The README's examples name files that exist in a clone (the defect: the replay example
//! pointed at `../shared/...`, which is not part of the repository).

#[test]
fn every_file_the_readme_commands_name_exists_in_the_repository() {
    let root = std::path::Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/.."));
    let readme = std::fs::read_to_string(root.join("README.md")).unwrap();
    // The commands: the text inside ``` fences.
    let commands: String = readme
        .split("```")
        .skip(1)
        .step_by(2)
        .collect::<Vec<_>>()
        .join("\n");
    let mut checked = 0;
    for word in commands.split(|c: char| c.is_whitespace() || "()[]`,".contains(c)) {
        let named_file = [".txt", ".toml", ".md", ".rs", ".obj", ".png"]
            .iter()
            .any(|ext| word.ends_with(ext))
            && word.contains('/')
            && !word.contains("://");
        if !named_file {
            continue;
        }
        assert!(
            !word.starts_with(".."),
            "{word} lies outside the repository"
        );
        // Files a command writes (`runs/...`) are not expected; repository paths are.
        let top = word.split('/').next().unwrap();
        if root.join(top).exists() {
            assert!(
                root.join(word).exists(),
                "README names {word}, which does not exist"
            );
            checked += 1;
        }
    }
    assert!(checked >= 1, "only {checked} paths checked");
}
