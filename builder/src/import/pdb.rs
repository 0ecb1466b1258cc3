//! Protein Data Bank (PDB) files: atoms as spheres.
//!
//! Reads the fixed columns of `ATOM` and `HETATM` records (waters and other
//! hetero groups included): x 31-38, y 39-46, z 47-54 and the element in
//! 77-78, or from the atom name in 13-16 when those are blank (two-letter
//! elements start in column 13, one-letter ones in 14). Only the first
//! `MODEL` is read (reading stops at the first `ENDMDL`), and only atoms
//! whose alternate location (column 17) is blank or `A`.
//!
//! Each atom becomes a sphere with its Bondi van der Waals radius (H 1.20,
//! C 1.70, N 1.55, O 1.52, S 1.80, P 1.80, F 1.47, Cl 1.75, Br 1.85, I 1.98,
//! Se 1.90, others 1.80 Å) and its Jmol CPK color (deep pink for elements
//! not in the table).

use std::fs::File;
use std::io::{BufRead, BufReader};
use std::path::Path;

use glam::DVec3;

use super::ImportError;
use crate::scene::{Geometry, Primitives, Rgb8, Scene};

/// Loads the atoms of a PDB file as spheres with per-atom colors.
pub fn load(path: &Path) -> Result<Scene, ImportError> {
    let file = File::open(path).map_err(|e| ImportError::io(path, e))?;
    let cap = file.metadata().map(|m| m.len() / 81).unwrap_or(0) as usize;
    let mut reader = BufReader::new(file);
    let (mut positions, mut radii, mut colors) = (
        Vec::with_capacity(cap),
        Vec::with_capacity(cap),
        Vec::with_capacity(cap),
    );
    let mut line = Vec::new();
    let mut line_no = 0u64;
    loop {
        line.clear();
        if reader
            .read_until(b'\n', &mut line)
            .map_err(|e| ImportError::io(path, e))?
            == 0
        {
            break;
        }
        line_no += 1;
        let record = column(&line, 1, 6);
        if record == "ENDMDL" {
            break;
        }
        if !(record == "ATOM" || record == "HETATM") || !matches!(column(&line, 17, 17), "" | "A") {
            continue;
        }
        let mut xyz = [0.0; 3];
        for (slot, (axis, start)) in xyz.iter_mut().zip([("x", 31), ("y", 39), ("z", 47)]) {
            let text = column(&line, start, start + 7);
            *slot = text.parse().map_err(|_| {
                let msg = format!("{axis} coordinate '{text}' is not a number");
                ImportError::malformed(path, format!("line {line_no}"), msg)
            })?;
        }
        let (radius, color) = style(&element(&line));
        positions.push(DVec3::from(xyz));
        radii.push(radius);
        colors.push(rgb(color));
    }
    let mut geometry = Geometry::new(
        path.display().to_string(),
        positions,
        Primitives::Spheres(radii),
    );
    geometry.colors = Some(colors);
    Ok(Scene::single(geometry))
}

/// Columns `first..=last` (1-based, as the PDB format counts them) of a
/// line, trimmed; empty where the line is shorter or not text.
fn column(line: &[u8], first: usize, last: usize) -> &str {
    let bytes = line
        .get(first - 1..last.min(line.len()))
        .unwrap_or_default();
    std::str::from_utf8(bytes).unwrap_or_default().trim()
}

/// The element symbol, upper case: columns 77-78, else from the atom name.
fn element(line: &[u8]) -> String {
    let symbol = column(line, 77, 78);
    if !symbol.is_empty() {
        return symbol.to_ascii_uppercase();
    }
    let name = line.get(12..16.min(line.len())).unwrap_or_default();
    let letters = name
        .iter()
        .filter(|b| b.is_ascii_alphabetic())
        .map(|&b| b.to_ascii_uppercase() as char);
    match name {
        // Four-character hydrogen names (HG21) also start in column 13.
        [b'H', _, _, last] if *last != b' ' => "H".into(),
        [first, ..] if first.is_ascii_alphabetic() => letters.take(2).collect(),
        _ => letters.take(1).collect(),
    }
}

/// Bondi van der Waals radius (Å) and Jmol CPK color (0xRRGGBB).
fn style(element: &str) -> (f64, u32) {
    match element {
        "H" | "D" => (1.20, 0xFFFFFF),
        "C" => (1.70, 0x909090),
        "N" => (1.55, 0x3050F8),
        "O" => (1.52, 0xFF0D0D),
        "S" => (1.80, 0xFFFF30),
        "P" => (1.80, 0xFF8000),
        "F" => (1.47, 0x90E050),
        "CL" => (1.75, 0x1FF01F),
        "BR" => (1.85, 0xA62929),
        "I" => (1.98, 0x940094),
        "SE" => (1.90, 0xFFA100),
        "FE" => (1.80, 0xE06633),
        "ZN" => (1.80, 0x7D80B0),
        "MG" => (1.80, 0x8AFF00),
        "CA" => (1.80, 0x3DFF00),
        "NA" => (1.80, 0xAB5CF2),
        "K" => (1.80, 0x8F40D4),
        "MN" => (1.80, 0x9C7AC7),
        "CU" => (1.80, 0xC88033),
        "CO" => (1.80, 0xF090A0),
        "NI" => (1.80, 0x50D050),
        _ => (1.80, 0xFF1493),
    }
}

/// A 0xRRGGBB color as bytes.
fn rgb(c: u32) -> Rgb8 {
    [(c >> 16) as u8, (c >> 8) as u8, c as u8]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::import::test_file::TestFile;

    fn color(element: &str) -> Rgb8 {
        rgb(style(element).1)
    }

    fn load_text(text: &str) -> Result<Geometry, ImportError> {
        let result = load(TestFile::new("t.pdb", text).path());
        result.map(|s| s.geometries.into_iter().next().unwrap())
    }

    /// One atom record in the fixed PDB columns.
    fn atom(record: &str, name: &str, alt: &str, xyz: [&str; 3], element: &str) -> String {
        let [x, y, z] = xyz;
        format!(
            "{record:<6}    1 {name:<4}{alt:1}ALA A   1    {x:>8}{y:>8}{z:>8}  1.00 20.00          {element:>2}\n"
        )
    }

    #[test]
    fn atoms_radii_and_colors() {
        let text = [
            "HEADER    TEST\n".to_string(),
            atom("ATOM", " N", "", ["-16.300", "-47.169", "4.756"], "N"),
            atom("ATOM", " CA", "A", ["1", "2", "3"], "C"),
            atom("ATOM", " CA", "B", ["9", "9", "9"], "C"),
            "ANISOU    3  CA BHIS A   0     1000   1000   1000      0      0      0       C\n"
                .into(),
            atom("HETATM", "FE", "", ["1", "2", "3"], ""),
            atom("HETATM", " O", "", ["0.5", "-0.25", "10"], "O"),
            atom("ATOM", "HG21", "", ["0", "0", "0"], ""),
            atom("ATOM", " CA", "", ["0", "0", "0"], ""),
            atom("ATOM", "UNK", "", ["1", "0", "0"], "XX"),
        ];
        let g = load_text(&text.concat()).unwrap();
        assert_eq!(g.positions.len(), 7);
        assert_eq!(g.positions[0], DVec3::new(-16.3, -47.169, 4.756));
        assert_eq!(g.positions[3], DVec3::new(0.5, -0.25, 10.0));
        let Primitives::Spheres(radii) = &g.primitives else {
            panic!()
        };
        assert_eq!(radii, &[1.55, 1.70, 1.80, 1.52, 1.20, 1.70, 1.80]);
        let colors = g.colors.unwrap();
        assert_eq!(colors[0], [0x30, 0x50, 0xF8]);
        assert_eq!(
            colors[1..],
            [
                color("C"),
                color("FE"),
                color("O"),
                color("H"),
                color("C"),
                [0xFF, 0x14, 0x93]
            ]
        );
        assert!(g.normals.is_none());
    }

    #[test]
    fn first_model_only() {
        let c = |x| atom("ATOM", " C", "", [x, "0", "0"], "C");
        let text = format!(
            "MODEL        1\n{}{}ENDMDL\nMODEL        2\n{}ENDMDL\nEND\n",
            c("1"),
            c("2"),
            c("3")
        );
        let g = load_text(&text).unwrap();
        assert_eq!(
            g.positions,
            vec![DVec3::new(1.0, 0.0, 0.0), DVec3::new(2.0, 0.0, 0.0)]
        );
    }

    #[test]
    fn bad_inputs() {
        assert!(matches!(
            load(Path::new("/nonexistent/x.pdb")),
            Err(ImportError::Io { .. })
        ));
        let e = load_text(&atom("ATOM", " C", "", ["1.0x0", "0", "0"], "C")).unwrap_err();
        assert!(
            e.to_string()
                .ends_with("line 1: x coordinate '1.0x0' is not a number"),
            "{e}"
        );
        let e = load_text("REMARK\nATOM      1  C   ALA A   1       1.000   0.0\n").unwrap_err();
        assert!(
            e.to_string()
                .contains("line 2: z coordinate '' is not a number"),
            "{e}"
        );
        // Short, odd and non-UTF-8 lines do not panic.
        assert!(load_text("ATOM\nHETATM \u{e9}\u{e9}\u{e9}\n\u{0}\n").is_err());
        let nan = atom("HETATM", " O", "", ["NaN", "0", "0"], "O");
        let e = TestFile::new("nan.pdb", nan).load_input().unwrap_err();
        assert!(
            e.to_string()
                .contains("vertex 0: coordinate is not a finite number"),
            "{e}"
        );
        let e = TestFile::new("empty.pdb", "HEADER\nEND\n")
            .load_input()
            .unwrap_err();
        assert!(matches!(e, ImportError::Empty { .. }));
    }
}
