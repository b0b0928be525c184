//! A minimal Wavefront OBJ reader: `v x y z` and `f a b c ...` lines (polygons are
//! fan-triangulated; `a/t/n` and negative indices are accepted); everything else is ignored.

/// A triangle mesh.
#[derive(Debug, Clone, Default, PartialEq)]
pub(crate) struct ObjMesh {
    pub(crate) vertices: Vec<[f64; 3]>,
    pub(crate) triangles: Vec<[u32; 3]>,
}

/// Parses OBJ text; the error is `(line, what is wrong)`.
pub(crate) fn parse(text: &str) -> Result<ObjMesh, (usize, String)> {
    let mut mesh = ObjMesh::default();
    for (index, line) in text.lines().enumerate() {
        let line_no = index + 1;
        let mut words = line.split_whitespace();
        match words.next() {
            Some("v") => {
                let mut v = [0.0; 3];
                for (i, c) in v.iter_mut().enumerate() {
                    let word = words
                        .next()
                        .ok_or((line_no, format!("vertex needs 3 coordinates, got {i}")))?;
                    *c = word
                        .parse::<f64>()
                        .ok()
                        .filter(|x| x.is_finite())
                        .ok_or((line_no, format!("bad vertex coordinate `{word}`")))?;
                }
                mesh.vertices.push(v);
            }
            Some("f") => {
                let count = mesh.vertices.len();
                let indices = words
                    .map(|w| {
                        vertex_index(w, count).ok_or((
                            line_no,
                            format!("bad face index `{w}` ({count} vertices so far)"),
                        ))
                    })
                    .collect::<Result<Vec<u32>, _>>()?;
                if indices.len() < 3 {
                    return Err((
                        line_no,
                        format!("face needs 3 vertices, got {}", indices.len()),
                    ));
                }
                for i in 1..indices.len() - 1 {
                    mesh.triangles
                        .push([indices[0], indices[i], indices[i + 1]]);
                }
            }
            _ => {}
        }
    }
    if mesh.triangles.is_empty() {
        return Err((text.lines().count().max(1), "mesh has no faces".to_string()));
    }
    Ok(mesh)
}

/// `word` is `i`, `i/t`, `i//n` or `i/t/n`; 1-based, negative counts from the end.
fn vertex_index(word: &str, count: usize) -> Option<u32> {
    let first = word.split('/').next()?;
    let i: i64 = first.parse().ok()?;
    let count = i64::try_from(count).ok()?;
    let zero_based = if i > 0 { i - 1 } else { count + i };
    (0..count)
        .contains(&zero_based)
        .then(|| u32::try_from(zero_based).ok())?
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quad_is_fan_triangulated() {
        let mesh = parse("# quad\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1/1 2//3 3 -1\n").unwrap();
        assert_eq!(mesh.vertices.len(), 4);
        assert_eq!(mesh.triangles, vec![[0, 1, 2], [0, 2, 3]]);
    }

    #[test]
    fn errors_name_the_line() {
        assert_eq!(parse("v 0 0 0\nv 1 x 0\n").unwrap_err().0, 2);
        assert_eq!(parse("v 0 0 0\nf 1 2 3\n").unwrap_err().0, 2);
        assert!(parse("v 0 0 0\n").is_err());
    }
}
