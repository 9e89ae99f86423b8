//! What the bridge reads from the robot model's URDF (the one the kinematics are built from):
//! its links, with their visuals, and its joints — for the joint names of `/joint_states` and
//! for the tests that keep the model drawable in Foxglove's URDF layer.
//!
//! A reader for robotd's own URDFs (`config/urdf/`, compiled into the kinematics), not a
//! general XML parser: elements, attributes in double or single quotes, comments. The
//! kinematics parse the same files with `urdf-rs`, so a file this reader misreads would not
//! build a robot either.

/// One `<link>`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Link {
    /// Its name (a frame in `/tf`).
    pub name: String,
    /// Its `<visual>` elements.
    pub visuals: usize,
    /// Its visuals that have both a geometry and a material colour.
    pub coloured_visuals: usize,
}

/// One `<joint>`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Joint {
    /// Its name (`joint_1`, `waist`).
    pub name: String,
    /// `revolute`, `continuous`, `prismatic`, `fixed`, …
    pub kind: String,
    /// The parent link.
    pub parent: String,
    /// The child link.
    pub child: String,
}

impl Joint {
    /// Whether it moves (has a position in a joint state).
    pub fn is_movable(&self) -> bool {
        !matches!(self.kind.as_str(), "fixed" | "floating" | "planar")
    }
}

/// The links and joints of a URDF, in file order.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Model {
    /// Every `<link>`.
    pub links: Vec<Link>,
    /// Every `<joint>`.
    pub joints: Vec<Joint>,
}

impl Model {
    /// The movable joints along a chain of links (`chain[i]` the parent of `chain[i + 1]`, as
    /// the kinematics' link poses list them), base first; `None` if two neighbours of the
    /// chain are not joined by a joint of the model.
    pub fn movable_joints_along(&self, chain: &[&str]) -> Option<Vec<&str>> {
        let mut names = Vec::new();
        for pair in chain.windows(2) {
            let joint = self
                .joints
                .iter()
                .find(|j| j.parent == pair[0] && j.child == pair[1])?;
            if joint.is_movable() {
                names.push(joint.name.as_str());
            }
        }
        Some(names)
    }
}

/// One tag: `<name attrs>`, `</name>` or `<name attrs/>`.
struct Tag<'a> {
    name: &'a str,
    attrs: &'a str,
    closing: bool,
    self_closing: bool,
}

fn tags(xml: &str) -> Vec<Tag<'_>> {
    let mut out = Vec::new();
    let mut rest = xml;
    while let Some(start) = rest.find('<') {
        rest = &rest[start..];
        if let Some(comment) = rest.strip_prefix("<!--") {
            let end = comment.find("-->").map_or(comment.len(), |e| e + 3);
            rest = &comment[end..];
            continue;
        }
        let Some(end) = rest.find('>') else {
            break;
        };
        let inner = &rest[1..end];
        rest = &rest[end + 1..];
        if inner.starts_with('?') || inner.starts_with('!') {
            continue;
        }
        let closing = inner.starts_with('/');
        let inner = inner.trim_start_matches('/').trim();
        let self_closing = inner.ends_with('/');
        let inner = inner.trim_end_matches('/').trim_end();
        let (name, attrs) = inner.split_once(char::is_whitespace).unwrap_or((inner, ""));
        out.push(Tag {
            name,
            attrs,
            closing,
            self_closing,
        });
    }
    out
}

/// The value of attribute `key` in `attrs` (`key="value"` or `key='value'`).
fn attr<'a>(attrs: &'a str, key: &str) -> Option<&'a str> {
    let mut rest = attrs;
    loop {
        let at = rest.find(key)?;
        let starts_word = rest[..at]
            .chars()
            .next_back()
            .is_none_or(char::is_whitespace);
        let after = rest[at + key.len()..].trim_start();
        if starts_word {
            if let Some(value) = after.strip_prefix('=') {
                let value = value.trim_start();
                let quote = value.chars().next()?;
                if quote == '"' || quote == '\'' {
                    let value = &value[1..];
                    return value.find(quote).map(|end| &value[..end]);
                }
            }
        }
        rest = &rest[at + key.len()..];
    }
}

/// The links and joints of `urdf`.
pub fn parse(urdf: &str) -> Model {
    let mut model = Model::default();
    // Where we are: inside a link, a joint, a visual of a link.
    let mut link: Option<Link> = None;
    let mut joint: Option<Joint> = None;
    let mut visual: Option<(bool, bool)> = None; // (has geometry, has colour)
    for tag in tags(urdf) {
        match (tag.name, tag.closing) {
            ("link", false) => {
                let new = Link {
                    name: attr(tag.attrs, "name").unwrap_or_default().to_owned(),
                    visuals: 0,
                    coloured_visuals: 0,
                };
                if tag.self_closing {
                    model.links.push(new);
                } else {
                    link = Some(new);
                }
            }
            ("link", true) => model.links.extend(link.take()),
            ("visual", false) if link.is_some() => {
                if let Some(link) = link.as_mut() {
                    link.visuals += 1;
                }
                visual = (!tag.self_closing).then_some((false, false));
            }
            ("visual", true) => {
                if let (Some((true, true)), Some(link)) = (visual.take(), link.as_mut()) {
                    link.coloured_visuals += 1;
                }
            }
            ("box" | "cylinder" | "sphere" | "mesh" | "capsule", false) => {
                if let Some(v) = visual.as_mut() {
                    v.0 = true;
                }
            }
            ("color", false) if attr(tag.attrs, "rgba").is_some() => {
                if let Some(v) = visual.as_mut() {
                    v.1 = true;
                }
            }
            ("joint", false) if link.is_none() => {
                let new = Joint {
                    name: attr(tag.attrs, "name").unwrap_or_default().to_owned(),
                    kind: attr(tag.attrs, "type").unwrap_or_default().to_owned(),
                    parent: String::new(),
                    child: String::new(),
                };
                if tag.self_closing {
                    model.joints.push(new);
                } else {
                    joint = Some(new);
                }
            }
            ("joint", true) => model.joints.extend(joint.take()),
            ("parent", false) => {
                if let Some(j) = joint.as_mut() {
                    j.parent = attr(tag.attrs, "link").unwrap_or_default().to_owned();
                }
            }
            ("child", false) => {
                if let Some(j) = joint.as_mut() {
                    j.child = attr(tag.attrs, "link").unwrap_or_default().to_owned();
                }
            }
            _ => {}
        }
    }
    model
}

#[cfg(test)]
mod tests {
    use super::*;
    use robotd_kinematics::{Kinematics, RobotModel};

    const MODELS: [RobotModel; 2] = [RobotModel::Ned2, RobotModel::WidowX250];

    #[test]
    fn every_link_of_both_robots_has_a_coloured_visual() {
        // Foxglove's URDF layer draws only visuals (or collision shapes): a link without one
        // is invisible, and a model without any shows no arm at all.
        for model in MODELS {
            let urdf = Kinematics::new(model).urdf();
            let parsed = parse(urdf);
            assert_eq!(
                parsed.links.len(),
                urdf.matches("<link ").count(),
                "{model:?}: every <link> read"
            );
            assert!(parsed.links.len() >= 10, "{model:?}: {parsed:?}");
            for link in &parsed.links {
                assert!(
                    link.visuals > 0 && link.coloured_visuals == link.visuals,
                    "{model:?}: link {} has {} visuals, {} with a geometry and a colour",
                    link.name,
                    link.visuals,
                    link.coloured_visuals
                );
            }
        }
    }

    #[test]
    fn the_joints_are_read_with_their_links() {
        let ned2 = parse(Kinematics::new(RobotModel::Ned2).urdf());
        assert_eq!(ned2.joints.len(), 9);
        let camera = ned2
            .joints
            .iter()
            .find(|j| j.name == "camera_joint")
            .unwrap();
        assert_eq!(
            (
                camera.kind.as_str(),
                camera.parent.as_str(),
                camera.child.as_str()
            ),
            ("fixed", "wrist_link", "camera_link")
        );
        let wx = parse(Kinematics::new(RobotModel::WidowX250).urdf());
        let movable: Vec<&str> = wx
            .joints
            .iter()
            .filter(|j| j.is_movable())
            .map(|j| j.name.as_str())
            .collect();
        assert_eq!(
            movable,
            [
                "waist",
                "shoulder",
                "elbow",
                "forearm_roll",
                "wrist_angle",
                "wrist_rotate"
            ]
        );
    }

    #[test]
    fn the_reader_takes_quotes_comments_and_self_closing_tags() {
        let model = parse(
            "<?xml version='1.0'?><!-- <link name=\"ghost\"/> --><robot>\
             <link name='a'/><link name=\"b\"><visual><geometry><box size='1 1 1'/></geometry>\
             <material name='m'><color rgba='1 0 0 1'/></material></visual><visual>\
             <geometry><sphere radius='1'/></geometry></visual></link>\
             <joint name=\"j\" type='continuous'><parent link='a'/><child link=\"b\"/></joint>\
             </robot>",
        );
        let links: Vec<(&str, usize, usize)> = model
            .links
            .iter()
            .map(|l| (l.name.as_str(), l.visuals, l.coloured_visuals))
            .collect();
        assert_eq!(links, [("a", 0, 0), ("b", 2, 1)]);
        assert_eq!(model.movable_joints_along(&["a", "b"]), Some(vec!["j"]));
        assert_eq!(model.movable_joints_along(&["b", "a"]), None);
        assert_eq!(attr("xname='x' name='y'", "name"), Some("y"));
    }
}
