// The parts of three.js the mtlc preview page uses, bundled as one classic script (global THREE).
export {
  AmbientLight, ArrowHelper, BufferGeometry, CapsuleGeometry, Color, ConeGeometry,
  CylinderGeometry, DirectionalLight, Float32BufferAttribute, GridHelper, Group,
  HemisphereLight, LineBasicMaterial, LineSegments, Matrix4, Mesh, MeshBasicMaterial,
  MeshLambertMaterial, MeshStandardMaterial, PerspectiveCamera, Plane, PlaneGeometry,
  Quaternion, Raycaster, REVISION, Scene, SphereGeometry, Vector2, Vector3, WebGLRenderer,
} from 'three';
export { OrbitControls } from 'three/examples/jsm/controls/OrbitControls.js';
