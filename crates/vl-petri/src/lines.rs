//! Line numbers for the XML readers' error messages, found by binary search
//! over where each line starts: asking roxmltree for a node's position
//! scans the text from its start, which made reading a wide net quadratic.

/// Where each line of a text starts.
pub(crate) struct LineStarts(Vec<usize>);

impl LineStarts {
    pub(crate) fn new(text: &str) -> LineStarts {
        let starts = std::iter::once(0)
            .chain(text.match_indices('\n').map(|(i, _)| i + 1))
            .collect();
        LineStarts(starts)
    }

    /// The 1-based line that byte `offset` is on.
    pub(crate) fn of(&self, offset: usize) -> u32 {
        u32::try_from(self.0.partition_point(|&start| start <= offset)).unwrap_or(u32::MAX)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn offsets_fall_on_their_lines() {
        let text = "a\nbc\n\nd";
        let lines = LineStarts::new(text);
        let naive = |offset: usize| text[..offset].matches('\n').count() as u32 + 1;
        for offset in 0..text.len() {
            assert_eq!(lines.of(offset), naive(offset), "at {offset}");
        }
    }
}
