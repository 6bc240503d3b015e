//! A direct parser for the commonest element of a large `objects` list: a plain sphere,
//!
//! ```ron
//! (name: "ball 7", shape: Sphere(center: (1.5, -2, 3e-1), radius: 0.25), material: (color: (0.1, 0.2, 0.3)))
//! ```
//!
//! [`parse_plain_sphere`] reads one such element without serde, about ten times faster than the
//! RON parser, and gives exactly the [`ObjectDesc`] the RON parser gives
//! ([`PlainSphere::into_desc`]) — or `None`, and the
//! caller parses it with RON. It accepts only a strict subset of what RON accepts:
//!
//! - the element is `(` fields `)`, the fields `name`, `shape` (required) and `material`, each at
//!   most once, in any order, separated by `,`, no trailing comma;
//! - `name` is a string without escapes or control characters (`"…"`);
//! - `shape` is `Sphere(` with fields `center` and `radius`, each at most once (defaults as in
//!   [`SphereDesc`]), and only while `Sphere` is still the built-in of that name in the registry;
//! - `material` is `(` with fields `color`, `specular`, `shininess`, each at most once
//!   (defaults as in [`Material`]);
//! - a vector is `(x, y, z)`; a number is `-?digits(.digits)?([eE][+-]?digits)?`, read as RON
//!   reads it (`f64::from_str` of the same text, correctly rounded);
//! - between tokens only spaces, tabs and line breaks (a comment gives `None`).
//!
//! Everything else (other fields or primitives, `Some(…)`, raw strings, escapes, comments,
//! trailing commas, `inf`, `1_000`, `1f64`, malformed text) gives `None`, so that what a file
//! means and every message about it (file:line:col, field) are those of the RON parser. Values
//! are not validated here: a negative radius parses, and the object build refuses it as it
//! refuses one parsed by RON.

use crate::scene::desc::{Material, ObjectDesc};
use crate::scene::shape_desc::ShapeDesc;
use crate::scene::shapes::SphereDesc;
use glam::DVec3;

/// A plain sphere element as [`parse_plain_sphere`] reads it: its name, sphere and material
/// descriptions (not validated).
#[derive(Debug)]
pub(crate) struct PlainSphere {
    pub(crate) name: Option<String>,
    pub(crate) sphere: SphereDesc,
    pub(crate) material: Material,
}

impl PlainSphere {
    /// The object description the RON parser gives for the same element.
    pub(crate) fn into_desc(self) -> ObjectDesc {
        ObjectDesc {
            name: self.name,
            shape: ShapeDesc {
                name: "Sphere",
                shape: Box::new(self.sphere),
            },
            transform: None,
            transform_close: None,
            material: self.material,
        }
    }
}

/// The plain sphere object `text` (one trimmed element of an `objects` list), or `None` where
/// the RON parser must read it (see the module docs). `sphere_is_builtin` says whether the
/// registry's `Sphere` is still the built-in one.
pub(crate) fn parse_plain_sphere(text: &str, sphere_is_builtin: bool) -> Option<PlainSphere> {
    if !sphere_is_builtin {
        return None;
    }
    let mut p = Cursor {
        bytes: text.as_bytes(),
        at: 0,
    };
    let mut name: Option<String> = None;
    let mut sphere: Option<SphereDesc> = None;
    let mut material: Option<Material> = None;
    p.fields(|p, field| match field {
        b"name" if name.is_none() => {
            name = Some(p.string()?.to_owned());
            Some(())
        }
        b"shape" if sphere.is_none() => {
            sphere = Some(p.sphere()?);
            Some(())
        }
        b"material" if material.is_none() => {
            material = Some(p.material()?);
            Some(())
        }
        _ => None,
    })?;
    if p.at != p.bytes.len() {
        return None;
    }
    Some(PlainSphere {
        name,
        sphere: sphere?,
        material: material.unwrap_or_default(),
    })
}

/// A position in the element's bytes.
struct Cursor<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl<'a> Cursor<'a> {
    fn skip_space(&mut self) {
        while matches!(self.bytes.get(self.at), Some(b' ' | b'\t' | b'\n' | b'\r')) {
            self.at += 1;
        }
    }

    /// Consumes `c` after optional space.
    fn expect(&mut self, c: u8) -> Option<()> {
        self.skip_space();
        (self.bytes.get(self.at) == Some(&c)).then(|| self.at += 1)
    }

    /// An identifier after optional space.
    fn ident(&mut self) -> Option<&'a [u8]> {
        self.skip_space();
        let start = self.at;
        while self
            .bytes
            .get(self.at)
            .is_some_and(|c| c.is_ascii_alphanumeric() || *c == b'_')
        {
            self.at += 1;
        }
        let ident = &self.bytes[start..self.at];
        ident.first().is_some_and(u8::is_ascii_alphabetic).then_some(ident)
    }

    /// `( field: value, … )`, each value read by `value(self, field)`; an empty `()` is allowed.
    fn fields(&mut self, mut value: impl FnMut(&mut Self, &[u8]) -> Option<()>) -> Option<()> {
        self.expect(b'(')?;
        self.skip_space();
        if self.bytes.get(self.at) == Some(&b')') {
            self.at += 1;
            return Some(());
        }
        loop {
            let field = self.ident()?;
            self.expect(b':')?;
            value(self, field)?;
            self.skip_space();
            match self.bytes.get(self.at)? {
                b',' => self.at += 1,
                b')' => {
                    self.at += 1;
                    return Some(());
                }
                _ => return None,
            }
        }
    }

    /// A string without escapes or control characters.
    fn string(&mut self) -> Option<&'a str> {
        self.expect(b'"')?;
        let start = self.at;
        loop {
            match *self.bytes.get(self.at)? {
                b'"' => break,
                b'\\' | 0..0x20 | 0x7f => return None,
                _ => self.at += 1,
            }
        }
        let s = std::str::from_utf8(&self.bytes[start..self.at]).ok()?;
        self.at += 1;
        Some(s)
    }

    /// A number in the grammar of the module docs.
    fn number(&mut self) -> Option<f64> {
        self.skip_space();
        let start = self.at;
        let digits = |p: &mut Self| {
            let from = p.at;
            while p.bytes.get(p.at).is_some_and(u8::is_ascii_digit) {
                p.at += 1;
            }
            (p.at > from).then_some(())
        };
        if self.bytes.get(self.at) == Some(&b'-') {
            self.at += 1;
        }
        digits(self)?;
        if self.bytes.get(self.at) == Some(&b'.') {
            self.at += 1;
            digits(self)?;
        }
        if matches!(self.bytes.get(self.at), Some(b'e' | b'E')) {
            self.at += 1;
            if matches!(self.bytes.get(self.at), Some(b'+' | b'-')) {
                self.at += 1;
            }
            digits(self)?;
        }
        // the RON parser reads on through these (`1.5.2`, `1f64`, `2_0`, `1e5e`): leave it to it
        if self
            .bytes
            .get(self.at)
            .is_some_and(|c| c.is_ascii_alphanumeric() || matches!(c, b'.' | b'_' | b'+' | b'-'))
        {
            return None;
        }
        // ASCII digits and signs only: valid UTF-8
        std::str::from_utf8(&self.bytes[start..self.at]).ok()?.parse().ok()
    }

    /// `(x, y, z)`.
    fn vector(&mut self) -> Option<DVec3> {
        self.expect(b'(')?;
        let x = self.number()?;
        self.expect(b',')?;
        let y = self.number()?;
        self.expect(b',')?;
        let z = self.number()?;
        self.expect(b')')?;
        Some(DVec3::new(x, y, z))
    }

    /// `Sphere(center: …, radius: …)`.
    fn sphere(&mut self) -> Option<SphereDesc> {
        // no space before the `(` (where RON's rules for it are subtle)
        if self.ident()? != b"Sphere" || self.bytes.get(self.at) != Some(&b'(') {
            return None;
        }
        let (mut center, mut radius) = (None, None);
        self.fields(|p, field| match field {
            b"center" if center.is_none() => {
                center = Some(p.vector()?);
                Some(())
            }
            b"radius" if radius.is_none() => {
                radius = Some(p.number()?);
                Some(())
            }
            _ => None,
        })?;
        Some(SphereDesc {
            center: center.unwrap_or(DVec3::ZERO),
            radius: radius.unwrap_or(1.0),
        })
    }

    /// `(color: …, specular: …, shininess: …)`.
    fn material(&mut self) -> Option<Material> {
        let defaults = Material::default();
        let (mut color, mut specular, mut shininess) = (None, None, None);
        self.fields(|p, field| match field {
            b"color" if color.is_none() => {
                color = Some(p.vector()?);
                Some(())
            }
            b"specular" if specular.is_none() => {
                specular = Some(p.number()?);
                Some(())
            }
            b"shininess" if shininess.is_none() => {
                shininess = Some(p.number()?);
                Some(())
            }
            _ => None,
        })?;
        Some(Material {
            color: color.unwrap_or(defaults.color),
            specular: specular.unwrap_or(defaults.specular),
            shininess: shininess.unwrap_or(defaults.shininess),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::desc::ron_options;

    /// The element's description by the fast path.
    fn parse_sphere_object(text: &str, sphere_is_builtin: bool) -> Option<ObjectDesc> {
        parse_plain_sphere(text, sphere_is_builtin).map(PlainSphere::into_desc)
    }

    /// The RON parser's reading of one element.
    fn by_ron(text: &str) -> Result<ObjectDesc, ron::error::SpannedError> {
        ron_options().from_str::<ObjectDesc>(text)
    }

    /// Elements the fast path must read, with spaces, orders, defaults and numbers of every form.
    const PLAIN: [&str; 12] = [
        "(shape: Sphere(center: (1, 2, 3), radius: 0.5))",
        "(shape: Sphere(center: (-65.70414455435402, 3.3140213009418427, 70.54614524897565), radius: 0.2887))",
        r#"(name: "ball 0", shape: Sphere(center: (1.5, -2.25, 3e-1), radius: 2E2), material: (color: (0.134, 0.847, 0.764)))"#,
        r#"(material: (shininess: 8, color: (1, 0, 0), specular: 0.5), shape: Sphere(radius: 1e-320), name: "é ✓ [a], b")"#,
        "(shape: Sphere())",
        "(shape: Sphere(radius: -1))",
        "(shape: Sphere(center: (0.1, 0.2, 0.3)), material: ())",
        "( shape :\tSphere(\n center : ( 1 , 2 , 3 ) ,\r\n radius : 4 ) )",
        "(shape: Sphere(center: (1e400, -0, 123456789012345678901234567890), radius: 0.30000000000000004))",
        "(shape: Sphere(center: (1.0e+5, 2.5E-3, 7e0), radius: 00012.500))",
        r#"(name: "", shape: Sphere(radius: 3))"#,
        "(shape: Sphere(center: (0.1, 0.2, 0.3), radius: 1.7976931348623157e308), material: (specular: -1))",
    ];

    /// Elements the fast path leaves to RON (valid or not).
    const OTHERS: [&str; 22] = [
        "(shape: Box(min: (0, 0, 0), max: (1, 1, 1)))",
        "(shape: Sphere(center: (1, 2, 3)), transform: (translate: (1, 0, 0)))",
        r#"(name: Some("a"), shape: Sphere())"#,
        r#"(name: "a\"b", shape: Sphere())"#,
        r##"(name: r#"a"#, shape: Sphere())"##,
        "(shape: Sphere(radius: 1,))",
        "(shape: Sphere(),)",
        "(shape: Sphere(radius: inf))",
        "(shape: Sphere(radius: 1_000))",
        "(shape: Sphere(radius: 1f64))",
        "(shape: Sphere(radius: +1))",
        "(shape: Sphere(radius: .5))",
        "(shape: Sphere(radius: 1.))",
        "(shape: Sphere(radius: 1 /* one */))",
        "(shape: Sphere (radius: 1))",
        "(shape: Sphere(radius: 1, radius: 2))",
        "(shape: Sphere(), shape: Sphere())",
        "(shape: Sphere(center: (1, 2)))",
        "(shape: Sphere(center: [1, 2, 3]))",
        "(name: \"a\")",
        "ObjectDesc(shape: Sphere())",
        "(shape: Sphere(colour: (1, 2, 3)))",
    ];

    /// Where the fast path reads an element, RON reads it too, to the same description (the
    /// `Debug` form prints every f64 exactly).
    fn assert_agrees(text: &str) -> bool {
        let Some(fast) = parse_sphere_object(text, true) else {
            return false;
        };
        match by_ron(text) {
            Ok(ron) => assert_eq!(format!("{fast:?}"), format!("{ron:?}"), "{text}"),
            Err(e) => panic!("the fast path read {text:?}, which RON refuses: {e}"),
        }
        true
    }

    #[test]
    fn plain_spheres_read_as_ron_reads_them() {
        for text in PLAIN {
            assert!(assert_agrees(text), "not read by the fast path: {text}");
        }
        let d = parse_sphere_object(PLAIN[2], true).unwrap();
        assert_eq!(d.name.as_deref(), Some("ball 0"));
        assert_eq!(d.material.color, DVec3::new(0.134, 0.847, 0.764));
        assert_eq!(d.material.shininess, 32.0);
        assert!(format!("{:?}", d.shape.shape).contains("center: DVec3(1.5, -2.25, 0.3), radius: 200.0"));
    }

    #[test]
    fn everything_else_is_left_to_ron() {
        for text in OTHERS {
            assert!(parse_sphere_object(text, true).is_none(), "{text}");
        }
        // a user type registered as `Sphere` is parsed as that type
        assert!(parse_sphere_object(PLAIN[0], false).is_none());
    }

    /// Every single-byte deletion, and every replacement or insertion of a byte likely to matter,
    /// at every position of every plain element: the fast path reads a mutant only where RON
    /// reads it to the same description, and leaves the rest (RON's errors) to RON.
    #[test]
    fn mutated_elements_read_as_ron_reads_them_or_are_left_to_it() {
        let bytes: &[u8] = b" ,:()\"-+.eE0159_/\\xa[";
        let (mut read, mut left) = (0, 0);
        for text in PLAIN {
            let mut mutants = Vec::new();
            for at in 0..text.len() {
                if !text.is_char_boundary(at) {
                    continue;
                }
                let next = (at + 1..=text.len())
                    .find(|&k| text.is_char_boundary(k))
                    .unwrap_or(text.len());
                mutants.push(format!("{}{}", &text[..at], &text[next..]));
                for &b in bytes {
                    let c = char::from(b);
                    mutants.push(format!("{}{c}{}", &text[..at], &text[next..]));
                    mutants.push(format!("{}{c}{}", &text[..at], &text[at..]));
                }
            }
            for mutant in mutants {
                if assert_agrees(&mutant) {
                    read += 1;
                } else {
                    left += 1;
                }
            }
        }
        // both kinds occur in numbers (e.g. a digit inserted into a number is read; a `,` in the
        // middle of one is not)
        assert!(read > 1000 && left > 1000, "read {read}, left {left}");
    }
}
