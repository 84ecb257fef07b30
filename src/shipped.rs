//! Inputs that ship inside the binary, so that README's commands run from
//! any directory: the example statecharts and nets (`examples/`), and the
//! Model Checking Contest manifest with the large models `vl petri bench`
//! times (`assets/petri-corpus/`, which the tests read too).

use std::path::Path;

use anyhow::Result;

use crate::BadInput;

/// A file that ships with vl: its path in the repository and its text.
struct Shipped {
    path: &'static str,
    text: &'static str,
}

impl Shipped {
    /// Whether `name` names this file: its repository path, its file name,
    /// or its file name without the extension.
    fn is(&self, name: &str) -> bool {
        let file = Path::new(self.path);
        name == self.path
            || file.file_name().is_some_and(|f| f == name)
            || file.file_stem().is_some_and(|f| f == name)
    }
}

macro_rules! shipped {
    ($($path:literal),* $(,)?) => {
        &[$(Shipped { path: $path, text: include_str!(concat!("../", $path)) }),*]
    };
}

const EXAMPLES: &[Shipped] = shipped![
    "examples/statecharts/mount.scxml",
    "examples/statecharts/execute.scxml",
    "examples/nets/producer-consumer.pnml",
];

/// The corpus's manifest: every model with its certified answers.
pub(crate) const CORPUS_MANIFEST: &str = include_str!("../assets/petri-corpus/manifest.csv");

/// The large models, by their path in the corpus.
const LARGE_MODELS: &[Shipped] = shipped![
    "assets/petri-corpus/core/Railroad-PT-010/model.pnml",
    "assets/petri-corpus/core/Kanban-PT-00005/model.pnml",
    "assets/petri-corpus/core/FMS-PT-00005/model.pnml",
    "assets/petri-corpus/core/Peterson-PT-3/model.pnml",
    "assets/petri-corpus/core/SwimmingPool-PT-02/model.pnml",
    "assets/petri-corpus/extra/DoubleExponent-PT-003/model.pnml",
];

/// A built-in corpus model by its path relative to the corpus directory.
pub(crate) fn corpus_model(pnml: &str) -> Option<&'static str> {
    let path = format!("assets/petri-corpus/{pnml}");
    LARGE_MODELS.iter().find(|m| m.path == path).map(|m| m.text)
}

/// The text of the file at `path`; when there is no such file, the
/// shipped example it names (`mount`, `producer-consumer.pnml`, or its
/// path in the repository) or the built-in corpus model at that path.
/// Anything else is bad input.
pub(crate) fn read_input(path: &Path) -> Result<String> {
    match std::fs::read_to_string(path) {
        Ok(text) => Ok(text),
        Err(e) => {
            let name = path.to_string_lossy();
            let example = EXAMPLES.iter().find(|x| x.is(&name));
            if let Some(example) = example.or_else(|| LARGE_MODELS.iter().find(|m| m.path == name))
            {
                return Ok(example.text.to_owned());
            }
            let hint = if e.kind() == std::io::ErrorKind::NotFound {
                let names: Vec<&str> = EXAMPLES.iter().map(|x| x.path).collect();
                format!(" (shipped examples: {})", names.join(", "))
            } else {
                String::new()
            };
            Err(BadInput(format!("cannot read {}: {e}{hint}", path.display())).into())
        }
    }
}
